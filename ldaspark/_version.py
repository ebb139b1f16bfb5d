"""The version string, on its own so that modules that stamp it import nothing else."""
__version__ = "0.2.0"
