"""`pip install .`: the module _hmap is built by CMake (target hmap_python, python/CMakeLists.txt),
the same build as `make build`, then packaged with the files of python/hmap.

HMAP_BUILD_DIR: the CMake build folder to use (an existing one is reused, so that `pip install .`
after `make build` only relinks; default build/pip); HMAP_BUILD_JOBS: parallel jobs (default 2).
Nothing is downloaded: CMake finds Debian's pybind11-dev and NumPy for this interpreter.
"""

import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = pathlib.Path(os.environ.get("HMAP_BUILD_DIR", ROOT / "build" / "pip")).resolve()
        if not (build_dir / "CMakeCache.txt").exists():
            generator = ["-G", "Ninja"] if shutil.which("ninja") else []
            subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build_dir), *generator, "-DCMAKE_BUILD_TYPE=Release",
                            "-DHMAP_BUILD_TESTS=OFF", "-DHMAP_BUILD_BENCH=OFF", "-DHMAP_PYTHON=ON",
                            f"-DPython3_EXECUTABLE={sys.executable}"], check=True)
        jobs = os.environ.get("HMAP_BUILD_JOBS", "2")
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "hmap_python", "--parallel", jobs], check=True)
        built = sorted((build_dir / "python" / "hmap").glob("_hmap*.so"))
        if not built:
            sys.exit(f"{build_dir}/python/hmap: no _hmap module was built")
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        # The module CMake built for this interpreter, under the name this interpreter imports.
        shutil.copyfile(built[-1], target)


setup(
    packages=["hmap"],
    package_dir={"hmap": "python/hmap"},
    package_data={"hmap": ["*.pyi", "py.typed"]},
    ext_modules=[Extension("hmap._hmap", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
    options={"build": {"build_base": "build/setuptools"}},  # beside build/pip, not among CMake's folders
)
