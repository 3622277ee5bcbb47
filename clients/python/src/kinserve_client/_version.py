"""The package's own version (the API version it speaks is in ``GENERATED_FROM``)."""

__version__ = "0.1.0"
