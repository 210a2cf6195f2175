"""The drivers behind the ``shadowlab`` commands that render and write a run directory:
:mod:`.compare` (``shadowlab compare``: the truth and N configurations on one scene) and
:mod:`.animate` (``shadowlab animate``: the same on every frame of an animated scene). The
argument parsing is :mod:`shadowlab.cli`; studies are :mod:`shadowlab.study`."""
