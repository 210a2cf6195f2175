"""shadowlab: real-time shadow techniques measured against an exact ray-traced ground truth."""
__version__ = "0.1.0"
