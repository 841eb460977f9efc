"""Build step of the hdservo wheel: the simulator and the simulator's data go into the package.

The metadata is in pyproject.toml.  This file adds what a wheel needs to work outside the
checkout (see hdservo/resources.py, which finds these files at run time):

* ``hdservo/_native/hdservo-sim`` and ``hdservo/_native/libhdsim.so``, built by the
  repository's ``make`` (the same targets as ``make sim``);
* ``hdservo/data/axes/*.toml`` and ``hdservo/data/scenarios/*.toml``, copied from
  ``sim/axes`` and ``sim/scenarios`` (the one source of those files).

The wheel is built from a checkout (``pip install ./host`` or ``pip wheel ./host``); an
editable install (``make setup``) copies nothing: the package then uses the checkout's
files directly.  It holds a native program, so it is tagged for this platform.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: make target -> file name in hdservo/_native
NATIVE = {"build/bin/hdservo-sim": "hdservo-sim", "build/lib/libhdsim.so": "libhdsim.so"}
#: checkout directory -> directory under hdservo/data
SIM_DATA = {"sim/axes": "axes", "sim/scenarios": "scenarios"}


def _fail(msg: str) -> None:
    sys.stderr.write(f"hdservo build: {msg}\n")
    raise SystemExit(2)


class BuildWithSimulator(build_py):
    """build_py that also builds the simulator and copies the axis files and scenarios."""

    def run(self) -> None:
        editable = getattr(self, "editable_mode", False)
        if not editable:
            # start from an empty build tree: a module removed from the source stays out of the wheel
            shutil.rmtree(Path(self.build_lib) / "hdservo", ignore_errors=True)
        super().run()
        if editable:
            return
        if not (ROOT / "Makefile").is_file() or not (ROOT / "sim").is_dir():
            _fail(f"{ROOT}: expected the hdservo checkout (Makefile, sim/) around host/; "
                  "build the wheel from a checkout: pip wheel ./host")
        pkg = Path(self.build_lib) / "hdservo"
        p = subprocess.run(["make", "--no-print-directory", "-C", str(ROOT), *NATIVE],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if p.returncode != 0:
            sys.stderr.write(p.stdout[-4000:])
            _fail(f"make {' '.join(NATIVE)} failed (exit {p.returncode})")
        native = pkg / "_native"
        native.mkdir(parents=True, exist_ok=True)
        for target, name in NATIVE.items():
            shutil.copy2(ROOT / target, native / name)
        for src, dst in SIM_DATA.items():
            out = pkg / "data" / dst
            out.mkdir(parents=True, exist_ok=True)
            for f in sorted((ROOT / src).glob("*.toml")):
                shutil.copy2(f, out / f.name)


class PlatformWheel(bdist_wheel):
    """Any Python 3, no Python ABI, this platform: the wheel carries a native program."""

    def finalize_options(self) -> None:
        super().finalize_options()
        self.root_is_pure = False

    def get_tag(self) -> tuple[str, str, str]:
        _, _, plat = super().get_tag()
        return "py3", "none", plat


class NativeDistribution(Distribution):
    """Marks the distribution as platform specific (platlib, platform wheel tag)."""

    def has_ext_modules(self) -> bool:
        return True


setup(cmdclass={"build_py": BuildWithSimulator, "bdist_wheel": PlatformWheel}, distclass=NativeDistribution)
