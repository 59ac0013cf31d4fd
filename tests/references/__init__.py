"""Plain-Python (and numpy) references of the package's compiled kernels, one per kernel, kept in one
place and used by the tests that compare the kernels with them bit for bit.

``tests/`` is on ``sys.path`` under pytest (the rootdir ``conftest.py``), so tests import them as
``from references.sonar import ...``. Each module names the kernels it specifies.
"""
