"""The default image sizes, one named constant for each use, and a size as the command line
writes it (``800x600``); every default is written here once."""
from __future__ import annotations

#: What a comparison is measured at unless a size is given: ``shadowlab compare``,
#: ``shadowlab tune`` (as compare) and a suite without ``size`` (docs/contracts.md#suite-files).
COMPARE_SIZE = (800, 600)
#: What ``shadowlab animate`` measures every frame of an animation at unless a size is given.
ANIMATE_SIZE = (320, 240)
#: What :func:`shadowlab.measurement.pipeline.measure_configs` (sweeps and tests, writing
#: nothing) measures at unless a size is given.
SWEEP_SIZE = (640, 480)
#: The window of ``shadowlab view`` unless a size is given (the lab re-renders it whenever the
#: camera moves: on llvmpipe a few frames a second).
VIEW_SIZE = (640, 480)


def size_text(size: tuple[int, int]) -> str:
    """(width, height) as the command line writes it: ``(800, 600)`` → ``'800x600'``."""
    return f"{size[0]}x{size[1]}"
