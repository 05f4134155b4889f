"""The compiled hot path (sniffer/_hot.c), built when a C compiler is there.

pyproject.toml holds everything else.  The extension is optional: where it does not build (no compiler,
no Python headers), the install goes on and sniffer/hot.py runs the pure-Python path, which gives the same
output (tests/test_hot_equal.py); `sniffer --version` says which path runs.
"""

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """build_ext that warns instead of failing: `optional=True` covers a compile error, not every way a
    machine without a compiler fails (a missing compiler can raise before the compile starts)."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as e:  # noqa: BLE001 - any failure to build leaves the pure-Python path, said once
            self.warn(f"sniffer._hot not built ({e}): the pure-Python path runs")

    def build_extension(self, ext) -> None:
        try:
            super().build_extension(ext)
        except Exception as e:  # noqa: BLE001 - as in run()
            self.warn(f"{ext.name} not built ({e}): the pure-Python path runs")


setup(
    ext_modules=[Extension("sniffer._hot", ["sniffer/_hot.c"], optional=True, extra_compile_args=["-O2"])],
    cmdclass={"build_ext": OptionalBuildExt},
)
