"""Pack what a machine without network access needs to run nlobs's GPU and many-core benchmarks (run.sh beside).

Such a machine (a GPU server image: Python 3.12, NumPy, SciPy, SymPy, matplotlib, JAX with CUDA, no way to fetch a
package) lacks CasADi, Dask and a few small pure-Python packages. This writes them to ``.offline/`` in the checkout
(git-ignored; carried with the checkout to that machine):

- ``casadi.tar.xz``: CasADi's core, from the CasADi installed here: the Python module, ``libcasadi`` and the plugins
  that need no third-party solver library (the integrators, linear solvers, root-finders, interpolants, the
  SQP methods). Ipopt and the other bundled solvers are left out: the benchmarks do not use them, and the whole wheel
  (93 MB) is more than such a transfer takes. CasADi's Linux wheels are built for the stable ABI (abi3), so this
  module loads in any Python from 3.11 on, on the same processor family.
- ``wheels/``: Dask, distributed, their dependencies that a scientific image lacks, and latex2mathml (nlobs's report),
  downloaded for the target Python (``--python-version``, default 3.12), at the versions installed here.

Run:  python benchmarks/offline/pack.py [--python-version 3.12] [--out .offline]
Then, on that machine, in the checkout:  bash benchmarks/offline/run.sh
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import io
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: pure-Python packages a scientific image lacks: Dask's scheduler and nlobs's report (the versions installed here)
WHEELS = ("dask", "distributed", "tornado", "tblib", "zict", "partd", "locket", "latex2mathml")

#: libraries a CasADi plugin may need besides CasADi's own (the C and C++ runtimes every Linux has)
SYSTEM_LIBS = ("libdl.so", "libstdc++.so", "libm.so", "libgcc_s.so", "libpthread.so", "libc.so", "ld-linux", "librt.so")


def needed(path: Path) -> list[str]:
    """The shared libraries `path` names as needed (its ELF dynamic section, read by readelf)."""
    out = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True).stdout
    return [line.split("[", 1)[1].rstrip("]") for line in out.splitlines() if "(NEEDED)" in line]


def casadi_core(out: Path) -> Path:
    """CasADi's module and the plugins that need nothing outside CasADi, as ``out/casadi.tar.xz``."""
    import casadi
    src = Path(casadi.__file__).parent
    own = {"libcasadi.so.3.7"} | {p.name + ".3.7" for p in src.glob("libcasadi_*_common.so")}
    keep = ["__init__.py", "casadi.py", "_casadi.so", "libcasadi.so.3.7"]
    keep += [p.name for p in src.glob("libcasadi_*_common.so.3.7")]
    skipped = []
    for plugin in sorted(src.glob("libcasadi_*.so")):
        if plugin.name.endswith("_common.so"):
            continue
        if plugin.stat().st_size > 2_000_000:   # the ONNX graph model (9 MB): not used by nlobs
            skipped.append(plugin.name)
            continue
        libs = needed(plugin)
        if all(lib in own or lib.startswith(SYSTEM_LIBS) for lib in libs):
            keep.append(plugin.name)
        else:
            skipped.append(plugin.name)
    path = out / "casadi.tar.xz"
    with tarfile.open(path, "w:xz", preset=6) as tar:
        for name in keep:
            real = (src / name).resolve()
            tar.add(real, arcname=f"casadi/{name}")
        info = tarfile.TarInfo("casadi/VERSION-PACKED")
        text = f"{casadi.__version__} from {src}\nleft out: {', '.join(skipped)}\n".encode()
        info.size = len(text)
        tar.addfile(info, io.BytesIO(text))
    print(f"CasADi {casadi.__version__}: {len(keep)} files ({sum((src / k).resolve().stat().st_size for k in keep) / 1e6:.1f} MB) "
          f"-> {path} ({path.stat().st_size / 1e6:.1f} MB); left out {len(skipped)} plugins that need other libraries")
    return path


def wheels(out: Path, python_version: str) -> Path:
    """The pure-Python wheels of :data:`WHEELS` for `python_version`, in ``out/wheels``."""
    dest = out / "wheels"
    shutil.rmtree(dest, ignore_errors=True)
    dest.mkdir(parents=True)
    pins = [f"{name}=={md.version(name)}" for name in WHEELS]
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--python-version", python_version,
           "--implementation", "py", "--implementation", "cp", "--platform", "any", "--platform", "manylinux2014_x86_64",
           "--platform", "manylinux_2_17_x86_64", "--platform", "manylinux_2_28_x86_64", "-q", "-d", str(dest), *pins]
    subprocess.run(cmd, check=True)
    got = sorted(p.name for p in dest.glob("*.whl"))
    print(f"{len(got)} wheels -> {dest} ({sum(p.stat().st_size for p in dest.glob('*.whl')) / 1e6:.1f} MB): {', '.join(got)}")
    return dest


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--python-version", default="3.12", help="the Python of the machine that runs the benchmarks")
    ap.add_argument("--out", default=str(ROOT / ".offline"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    casadi_core(out)
    wheels(out, args.python_version)
    total = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"{out}: {total / 1e6:.1f} MB in all")
    return 0


if __name__ == "__main__":
    sys.exit(main())
