"""camsmooth: five-axis tool-axis smoothing for toroidal cutters."""

__version__ = "0.1.0"
