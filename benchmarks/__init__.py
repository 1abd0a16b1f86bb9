"""Speed benchmarks beside peers: one ``bench_<topic>.py`` script per topic, sharing
``_common.py``; ``run_all.py`` runs them all and writes ``docs/benchmarks.md``.

Each script runs as a file (``python benchmarks/bench_render.py``) or as a module
(``python -m benchmarks.bench_render``); ``test_run_all.py`` tests the harness's bookkeeping
and is collected by the project's test command (``testpaths`` in ``pyproject.toml``).
"""
