"""The failures collection: each shrunk failure as a scenario file, ready to replay.

A failure's file is exactly the scenario its minimal episode ran (``runs: 1``, its seed, its name),
so ``crossroads evaluate FILE --policy POLICY`` runs that episode again. A comment header says
where it came from. Files are written atomically (a temporary file renamed into place).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import yaml

from crossroads.scenario.spec import ScenarioSpec


def failure_yaml(spec: ScenarioSpec, *, header: Iterable[str] = ()) -> str:
    """The scenario as YAML (every field, in the model's order), under ``#`` comment lines."""
    lines = [f"# {line}" if line else "#" for line in header]
    body = yaml.safe_dump(spec.model_dump(mode="json"), sort_keys=False, allow_unicode=True,
                          default_flow_style=False, width=100)
    return "\n".join(lines) + ("\n" if lines else "") + body


def write_failure(directory: str | Path, spec: ScenarioSpec, *, header: Iterable[str] = ()) -> Path:
    """Write ``<directory>/<spec.name>.yaml``; its path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    final = directory / f"{spec.name}.yaml"
    tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
    tmp.write_text(failure_yaml(spec, header=header), encoding="utf-8")
    os.replace(tmp, final)
    return final
