"""Commands of the linecam study (filled in below)."""


def commands() -> list:
    return []
