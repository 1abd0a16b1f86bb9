"""pytest's set-up of the tests: the toy studies of ``tests/toys/`` importable by their own
module names (``import toy_study``, ``from plan_toy import TOY``).

The folder goes on ``sys.path`` of the test process before any test module is collected.
Worker processes find the toys the same way: a forked worker inherits the path, and a
spawned one (a local process or a Dask worker) receives the parent's ``sys.path`` from
:mod:`multiprocessing` before it unpickles a study, so it imports the toy's module by the
same name. A child interpreter a test starts itself (``subprocess``) has neither: such a
test puts ``tests/toys`` on its child's path itself.
"""

import sys
from pathlib import Path

#: the folder of the toy studies
TOYS = Path(__file__).resolve().parent / "toys"

if str(TOYS) not in sys.path:
    sys.path.insert(0, str(TOYS))
