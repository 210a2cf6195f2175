"""Package discovery for setuptools; everything else is in pyproject.toml.

Every package under ``shadowlab/`` is found, not listed: a package missing from a hand-written
list (``shadowlab.tuning``) broke every command of a plain, non-editable install while the
editable install of the tests hid it (issue 36). The repository's ``shaders/`` folder is installed
as ``shadowlab/shaders``, where :func:`shadowlab.gl.shader_dir` finds it.
"""
from setuptools import find_packages, setup

setup(packages=find_packages(include=["shadowlab", "shadowlab.*"]) + ["shadowlab.shaders"],
      package_dir={"shadowlab.shaders": "shaders"})
