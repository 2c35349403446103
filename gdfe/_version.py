"""The package version (one place; ``gdfe.__version__``)."""

__version__ = "0.1.0"
