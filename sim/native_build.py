"""``python -m sim.native_build``: compile ``sim.native.MODULES`` with mypyc into ``build/native`` when stale."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from sim.native import GROUP, MODULES, NATIVE_DIR, ROOT, is_fresh, manifest


def build(native_dir: Path = NATIVE_DIR, root: Path = ROOT) -> str:
    """Compile ``MODULES`` into ``native_dir`` unless a fresh build is there; what was done, in a line. Raises
    ``RuntimeError`` (with the compiler's last words) when the build fails; ``native_dir`` is then left empty."""
    if is_fresh(native_dir, root):
        return f"compiled modules up to date in {native_dir}"
    shutil.rmtree(native_dir, ignore_errors=True)
    sources = manifest(root)  # as they are when compiled: a file edited during the build leaves the build stale
    with tempfile.TemporaryDirectory(prefix="seapick-native-") as tmp:
        script = (
            "from setuptools import setup\n"
            "from mypyc.build import mypycify\n"
            f"setup(name={GROUP!r}, ext_modules=mypycify({list(MODULES)!r}, group_name={GROUP!r},"
            f" target_dir={str(Path(tmp) / 'c')!r}),"
            f" script_args=['-q', 'build_ext', '--build-lib', {str(Path(tmp) / 'lib')!r},"
            f" '--build-temp', {str(Path(tmp) / 'o')!r}])\n"
        )
        proc = subprocess.run(
            [sys.executable, "-c", script], cwd=root, capture_output=True, text=True, env=_build_env(), check=False
        )
        if proc.returncode != 0:
            tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-15:])
            raise RuntimeError(f"mypyc failed (exit {proc.returncode}):\n{tail}")
        native_dir.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(Path(tmp) / "lib", native_dir)
    from mypy.version import __version__ as mypy_version  # for the record: the build does not depend on it

    (native_dir / "manifest.json").write_text(json.dumps(sources | {"mypy": mypy_version}, indent=1) + "\n")
    return f"compiled {len(MODULES)} modules into {native_dir}"


def _build_env() -> dict[str, str]:
    env = dict(os.environ)
    env["SEAPICK_NATIVE"] = "0"  # mypyc reads the sources, never a compiled copy
    return env


def main() -> int:
    """``python -m sim.native_build``: build when stale. A failed build is reported, not fatal: plain Python runs."""
    try:
        print(f"sim.native_build: {build()}")
    except (RuntimeError, OSError) as e:
        print(f"sim.native_build: not compiled, the simulator runs as plain Python: {e}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
