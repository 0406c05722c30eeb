"""The wheel's packages, found rather than listed, so that a new package cannot be left out: pchc_rsl's own, and the
envs/, robots/ and configs/ folders installed as pchc_rsl.envs, pchc_rsl.robots and pchc_rsl.configs (nothing generic
such as ``envs`` lands in site-packages). Everything else is in pyproject.toml."""

from setuptools import find_packages, setup

MAPPED = {"pchc_rsl.envs": "envs", "pchc_rsl.robots": "robots", "pchc_rsl.configs": "configs"}
"""Import name -> the top-level folder it is installed from."""

packages = find_packages(include=["pchc_rsl", "pchc_rsl.*"])
for name, folder in MAPPED.items():
    packages += [name] + [f"{name}.{sub}" for sub in find_packages(folder)]

setup(packages=packages, package_dir={"pchc_rsl": "pchc_rsl", **MAPPED})
