"""The command line: a thin layer over the Python API (camsmooth.cli.main.main)."""
