"""The drivers behind the ``shadowlab`` commands that render and write a run directory, or read a
finished study: :mod:`.compare` (``shadowlab compare``: the truth and N configurations on one
scene), :mod:`.animate` (``shadowlab animate``: the same on every frame of an animated scene),
:mod:`.tune`, :mod:`.cost` (cost models from a study's rows) and :mod:`.pick` (the cheapest
configuration within an error budget). The argument parsing is :mod:`shadowlab.cli`; studies are
:mod:`shadowlab.study`."""
