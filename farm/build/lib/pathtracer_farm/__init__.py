"""Render pathtracer scenes on many machines through Dask.

The renderer plans the parts (``pathtracer --part K/N``) and merges them exactly
(``pathtracer merge``); this package runs the parts as Dask tasks, retries what failed,
resumes an interrupted job from the parts already on disk, and merges.
"""

__version__ = "0.1.0"
