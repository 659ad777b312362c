"""The workbench's version, and the versions of what produced an output (every output
records them beside its settings and timings)."""

from __future__ import annotations

import platform
from importlib import metadata

__version__ = "0.1.0"

# Short names an output records -> the distribution that installs them.
DISTRIBUTIONS = {"opencv": "opencv-contrib-python-headless"}


def versions(*names: str) -> dict[str, str]:
    """The workbench's and Python's versions, and the installed version of each of
    ``names`` (a distribution, or a short name of DISTRIBUTIONS), read from the installed
    metadata without importing it; a name that is not installed is left out."""
    found = {"workbench": __version__, "python": platform.python_version()}
    for name in names:
        try:
            found[name] = metadata.version(DISTRIBUTIONS.get(name, name))
        except metadata.PackageNotFoundError:
            continue
    return found
