"""Package discovery for setuptools; everything else is in pyproject.toml.

Every package under ``shadowlab/`` is found, not listed: a package missing from a hand-written
list (``shadowlab.tuning``) broke every command of a plain, non-editable install while the
editable install of the tests hid it (issue 36). The GLSL files sit beside the modules that use
them and ship as package data of their packages (pyproject.toml).
"""
from setuptools import find_namespace_packages, setup

# Namespace discovery so that the data folders without an ``__init__.py`` (scenes/meshes,
# suites/scaling, output/templates) are packages of their own too: setuptools warns, and will
# refuse, when an importable folder that ships data is missing from ``packages``.
setup(packages=find_namespace_packages(include=["shadowlab", "shadowlab.*"], exclude=["*.__pycache__"]))
