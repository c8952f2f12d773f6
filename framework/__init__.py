"""driftframe's core: world and stage order, fixed-step loop, frame math, storage."""

__version__ = "0.1.0"
