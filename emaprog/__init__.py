"""emaprog: model-based fault identification and prognostics for flight-control EMAs."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("emaprog")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__"]
