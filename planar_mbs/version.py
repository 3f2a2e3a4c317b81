"""The package's version, on its own so that any stage can stamp it on what it writes without
importing the package's facade (`planar_mbs/__init__.py`); pyproject.toml gives the same number."""
__version__ = "0.1.0"
