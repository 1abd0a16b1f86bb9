"""The house's infrastructure, shared by the world (:mod:`simcam`) and the lab (:mod:`budget`).

No physics and no instrument lives here: the error types a user's mistake raises
(:mod:`~simcam.infra.errors`), safe writing of outputs (:mod:`~simcam.infra.outputs`), process
lifecycle under signals and faults (:mod:`~simcam.infra.lifecycle`) and the command-line helpers
(:mod:`~simcam.infra.cli`, the only module here that imports click). Nothing in this package
imports the rest of :mod:`simcam` or :mod:`budget` (``tests/test_layers.py`` checks it). It sits
inside the ``simcam`` import package because the distribution's top level is two import
packages, ``simcam`` and ``budget``.
"""
