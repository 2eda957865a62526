"""Load user-written YAML into pydantic models with errors a person can act on.

Every problem becomes one :class:`SpecError` whose message names the file, the field path
(``approaches.2.entrance_lanes.0.turns.1``) and what is wrong, so a typo in a scenario or an
intersection file is found without reading a traceback. Used for intersection specs, scenario
files and the API.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)


class SpecError(ValueError):
    """A user-written specification (file or mapping) is missing, unreadable or invalid.

    ``problems`` holds ``(field_path, message)`` pairs; ``source`` names the file (or ``"<data>"``).
    """

    def __init__(self, source: str, problems: Iterable[tuple[str, str]]) -> None:
        self.source = source
        self.problems: tuple[tuple[str, str], ...] = tuple(problems)
        lines = [f"{source}: {len(self.problems)} problem(s)"]
        for field, message in self.problems:
            lines.append(f"  - {field or '<root>'}: {message}")
        super().__init__("\n".join(lines))

    @property
    def fields(self) -> tuple[str, ...]:
        """The field paths that have a problem, in order."""
        return tuple(field for field, _ in self.problems)


class FieldProblem(ValueError):
    """Raise from a model-level validator to report a problem at a nested field.

    Pydantic gives errors of ``model_validator``s the model's own location; this carries the
    dotted path below it (``approaches.2.bearing_deg``) so :class:`SpecError` can name the field.
    """

    def __init__(self, path: str, message: str) -> None:
        self.path = path
        self.message = message
        super().__init__(f"{path}: {message}")


def field_path(loc: Iterable[int | str]) -> str:
    """Join a pydantic error location into a dotted path (``("a", 2, "b") -> "a.2.b"``)."""
    return ".".join(str(part) for part in loc)


def problems_of(error: ValidationError) -> list[tuple[str, str]]:
    """Every pydantic error as ``(field_path, message)``, with the offending value where short."""
    problems = []
    for err in error.errors(include_url=False):
        cause = (err.get("ctx") or {}).get("error")
        if isinstance(cause, FieldProblem):
            problems.append((field_path([*err["loc"], cause.path]), cause.message))
            continue
        message = err["msg"]
        # "Value error, ..." is pydantic's prefix for our own validators: the rest says it all.
        message = message.removeprefix("Value error, ")
        value = err.get("input")
        if err["type"] not in ("missing",) and _is_short(value):
            message = f"{message} (got {value!r})"
        problems.append((field_path(err["loc"]), message))
    return problems


def _is_short(value: Any) -> bool:
    return isinstance(value, (str, int, float, bool)) and len(repr(value)) <= 60


def validate_model(data: Any, model: type[ModelT], source: str = "<data>") -> ModelT:
    """Validate already-parsed data (e.g. an API body) into ``model``, raising :class:`SpecError`."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise SpecError(source, problems_of(exc)) from None


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file, turning a missing file or a syntax error into :class:`SpecError`."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(source, [("", "file not found")]) from None
    except OSError as exc:
        raise SpecError(source, [("", f"cannot read the file: {exc.strerror or exc}")]) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise SpecError(source, [("", f"YAML syntax error at {where}{problem}")]) from None


def load_yaml_model(path: str | Path, model: type[ModelT]) -> ModelT:
    """Read ``path`` (YAML) and validate it into ``model``; any problem raises :class:`SpecError`."""
    data = load_yaml(path)
    if not isinstance(data, Mapping):
        kind = "an empty file" if data is None else f"a {type(data).__name__}"
        raise SpecError(str(path), [("", f"expected a mapping of fields at the top level, got {kind}")])
    return validate_model(data, model, source=str(path))
