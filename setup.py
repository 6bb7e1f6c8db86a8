"""Build configuration beyond pyproject.toml: the profile data package.

``profiles/`` stays at the top of the repository (it is data, edited by lab people) and
installs as ``stand.profile_data``; pyproject's package finder cannot add a package that
lives outside its parent's folder, so the list of packages is made here.
"""

from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["stand*", "bus*", "api*"]), "stand.profile_data"])
