"""The installed version (from package metadata), without importing anything heavy."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("hapticframe")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
