"""Shared helpers of the studies' figures: a saved figure with its caption, titles that fit,
histograms that stay visible where they overlap.

A study's report section places each figure in its Markdown with the caption right under it
(:func:`figure_markdown`); the caption states the figure's finding with numbers computed from
the arrays the figure draws, never a fixed sentence. :func:`save` checks, before writing, that
every title lies inside the figure (a clipped title is a bug, raised, never a silent PNG).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["Figure", "figure_markdown", "fit_titles", "overlaid_hist", "plt", "save", "titles_outside"]


class Figure(type(Path())):
    """A saved figure's path with its ``caption`` (Markdown, one paragraph)."""

    caption: str = ""

    def with_caption(self, caption: str) -> "Figure":
        self.caption = caption
        return self


def plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt_

    return plt_


def titles_outside(fig) -> list[str]:
    """The titles (axes titles, suptitle) whose drawn extent leaves the figure, after a draw."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    texts = [fig._suptitle] if getattr(fig, "_suptitle", None) is not None else []
    for ax in fig.axes:
        texts += [ax.title, ax._left_title, ax._right_title]
    bad = []
    for t in texts:
        if not t.get_visible() or not t.get_text():
            continue
        e = t.get_window_extent(renderer)
        # half a pixel: the renderer's rounding
        if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 or e.y1 > box.y1 + 0.5:
            bad.append(t.get_text())
    return bad


def fit_titles(fig, *, min_size: float = 6.0) -> bool:
    """Shrink the font of any title that does not fit its figure (down to ``min_size``), then
    wrap it at the widest word boundary that fits; the figure's layout is redone each step.
    True when every title fits (checked after the last change)."""
    import textwrap

    for _ in range(12):
        fig.tight_layout()
        bad = set(titles_outside(fig))
        if not bad:
            return True
        for ax in fig.axes:
            for t in (ax.title, ax._left_title, ax._right_title):
                if t.get_text() in bad:
                    if t.get_fontsize() > min_size:
                        t.set_fontsize(max(min_size, t.get_fontsize() - 1))
                    else:
                        text = t.get_text().replace("\n", " ")
                        lines = max(2, t.get_text().count("\n") + 2)
                        t.set_text(textwrap.fill(text, width=max(10, len(text) // lines + 1)))
    return False


def save(fig, path, caption: str, *, dpi: int = 110, layout: bool = True) -> Figure:
    """Lay out (``layout``: tight layout, and titles that do not fit shrunk or wrapped by
    :func:`fit_titles`; False: the caller's layout is kept), check every title fits, write
    ``path``, close; return the path with its caption."""
    p = plt()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # fit_titles has checked the titles after its last change (one draw less)
    bad = [] if layout and fit_titles(fig) else titles_outside(fig)
    if bad:  # pragma: no cover - fit_titles wraps until it fits
        p.close(fig)
        raise RuntimeError(f"{path.name}: title does not fit the figure: {bad}")
    fig.savefig(path, dpi=dpi)
    p.close(fig)
    return Figure(path).with_caption(caption)


def overlaid_hist(ax, samples: dict, *, bins=40, **kw) -> np.ndarray:
    """Histograms of several samples on one axes, every one visible where they overlap: common
    bin edges, a light fill under a solid outline per sample, distinct line styles; returns
    the edges. ``samples``: label -> array."""
    arrays = [np.asarray(v, dtype=float) for v in samples.values()]
    arrays = [a[np.isfinite(a)] for a in arrays]
    allv = np.concatenate(arrays) if arrays else np.zeros(1)
    lo, hi = (float(allv.min()), float(allv.max())) if allv.size else (0.0, 1.0)
    if hi <= lo:
        lo, hi = lo - 0.5 * (abs(lo) or 1.0), hi + 0.5 * (abs(hi) or 1.0)
    edges = np.linspace(lo, hi, (bins if np.isscalar(bins) else len(bins) - 1) + 1)
    styles = ("-", "--", ":", "-.")
    for i, (label, a) in enumerate(zip(samples, arrays)):
        color = f"C{i}"
        ax.hist(a, bins=edges, histtype="stepfilled", alpha=0.18, color=color, **kw)
        ax.hist(a, bins=edges, histtype="step", lw=1.6, ls=styles[i % len(styles)], color=color,
                label=label, **kw)
    return edges


def figure_markdown(figures) -> str:
    """Each figure's Markdown image with its caption under it (one paragraph each)."""
    out = []
    for f in figures:
        out += [f"![{Path(f).stem}]({Path(f).name})", "", f"**{Path(f).stem}**: {getattr(f, 'caption', '')}".rstrip(), ""]
    return "\n".join(out).rstrip()
