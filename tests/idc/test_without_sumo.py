"""The control contract is free of SUMO: every module of ``crossroads.idc`` (and the observation,
snapshot and outcome it reads) imports in a Python where ``libsumo`` cannot be imported, so a
controller can be written, loaded and tested without SUMO (only ``sim/sumo.py`` imports libsumo)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

BLOCK_SUMO = textwrap.dedent("""
    import importlib, pkgutil, sys

    class NoSumo:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("libsumo", "traci"):
                raise ImportError(f"{name} is blocked")
            return None

    sys.meta_path.insert(0, NoSumo())
""")


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", BLOCK_SUMO + textwrap.dedent(code)],
                          capture_output=True, text=True, timeout=120)


def test_every_idc_module_imports_without_libsumo() -> None:
    done = _run("""
        import crossroads.idc
        names = [m.name for m in pkgutil.walk_packages(crossroads.idc.__path__, "crossroads.idc.")]
        names += ["crossroads.sim.observation", "crossroads.sim.outcome", "crossroads.sim.snapshot"]
        for name in names:
            importlib.import_module(name)
        assert "libsumo" not in sys.modules
        print(len(names))
    """)
    assert done.returncode == 0, done.stderr[-3000:]
    assert int(done.stdout.split()[-1]) >= 10  # the idc modules and the three of the contract


def test_the_block_holds_for_the_world() -> None:
    """The check can fail: the world itself needs libsumo, and there the block stops it."""
    done = _run("import crossroads.sim.world")
    assert done.returncode != 0 and "libsumo is blocked" in done.stderr
