"""Package discovery for setuptools; everything else is in pyproject.toml.

The code packages are found automatically (find_packages), so a new subpackage is always in the
wheel; the data packages fraytool.shaders and fraytool.scenes map the top-level shaders/ and scenes/
folders (pyproject.toml, [tool.setuptools.package-dir]) and are named here because they have no
__init__.py to be found by.
"""
from setuptools import find_packages, setup

setup(packages=find_packages(include=["fraytool", "fraytool.*"])
      + ["fraytool.shaders", "fraytool.scenes", "fraytool.scenes.stress", "fraytool.scenes.assets"])
