"""The shared kernel every package of the workbench builds on.

User errors (``errors``), field validation for file formats (``validation``), the
physical conventions (``conventions``), atomic file writes (``files``), timing one call
(``timing``), study figures (``plots``), the dask executor (``executor``) and the
version (``version``). This package imports no other package of the project (the import
check in tests/test_architecture.py keeps it so), and nothing here imports the command
line: rcwa, renderer, calibration, datasets_synthetic and reports depend on it, and the
face (``workbench.cli``, ``workbench.demo``) depends on them.
"""
