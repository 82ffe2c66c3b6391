"""Packages for setuptools: every `brdflab` package found on disk (no hand-kept list to forget),
plus the shipped data folders mapped into the package. Everything else is in pyproject.toml."""

from setuptools import find_packages, setup

DATA_PACKAGES = {"brdflab._shaders": "shaders", "brdflab._materials": "materials", "brdflab._resources": "resources"}

setup(
    packages=find_packages(include=["brdflab", "brdflab.*"]) + list(DATA_PACKAGES),
    package_dir=DATA_PACKAGES,
)
