"""The installed robotcal distribution's version, read once from ``importlib.metadata`` (pyproject.toml's
``version``): what the root package's ``__version__``, the result folders' markers, the provenance records, the
report and ``robotcal --version`` all say. The lowest layer, so that no module needs the root package for it."""

from functools import cache
from importlib.metadata import version

__all__ = ["installed_version"]


@cache
def installed_version() -> str:
    """The installed distribution's version string (read once per process)."""
    return version("robotcal")
