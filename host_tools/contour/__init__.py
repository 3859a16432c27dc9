"""Host tools for the contour CNC axis drive."""

__version__ = "0.1.0"
