"""The one packaging step pyproject.toml cannot say: the data-only packages carry no modules.

fcb_sim._firmware is firmware/ and term._docs is docs/ (pyproject.toml, [tool.setuptools]): the wheel takes their
sources and pages, not firmware/gen_c.py nor docs/gen_*.py, which generate files in a clone and import the clone's
layout (``from docs import ...``), so installed they would be modules that cannot be imported.
"""

from setuptools import setup
from setuptools.command.build_py import build_py

DATA_ONLY = ("fcb_sim._firmware", "term._docs")


class BuildPy(build_py):
    def find_package_modules(self, package: str, package_dir: str) -> list[tuple[str, str, str]]:
        return [] if package in DATA_ONLY else super().find_package_modules(package, package_dir)


setup(cmdclass={"build_py": BuildPy})
