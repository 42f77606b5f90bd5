"""DensePeds: pedestrian tracking in dense crowds."""

from densepeds._core import __version__

__all__ = ["__version__"]
