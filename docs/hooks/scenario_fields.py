"""MkDocs hook: the scenario guide's field table, generated from the scenario's JSON Schema.

A page that holds the line ``<!-- scenario-fields -->`` gets, in its place, one table row per
field of a scenario file (nested fields as ``ego.start_distance_m``) with its type, default,
bounds and description, read from :func:`crossroads.scenario.spec.scenario_json_schema`.
So the guide lists exactly what the validator accepts, whoever changes the format next.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

MARKER = "<!-- scenario-fields -->"
BOUNDS = (("minimum", "≥"), ("exclusiveMinimum", ">"), ("maximum", "≤"), ("exclusiveMaximum", "<"),
          ("minLength", "length ≥"), ("maxLength", "length ≤"))


def on_page_markdown(markdown: str, **_: Any) -> str:
    """Replace the marker with the generated table (pages without it are returned as they are)."""
    if MARKER not in markdown:
        return markdown
    from crossroads.scenario.spec import scenario_json_schema  # only where the table is asked for

    return markdown.replace(MARKER, fields_table(scenario_json_schema()))


def fields_table(schema: dict[str, Any]) -> str:
    """The Markdown table of every field of ``schema``, objects expanded into their fields."""
    rows = ["| field | type | default | bounds | meaning |", "|---|---|---|---|---|"]
    required = set(schema.get("required", ()))
    for name, prop in schema["properties"].items():
        for path, field, is_required in _flatten(name, prop, schema["$defs"], name in required):
            rows.append(_row(path, field, is_required, schema["$defs"]))
    return "\n".join(rows)


def _flatten(path: str, prop: dict[str, Any], defs: dict[str, Any],
             required: bool) -> Iterator[tuple[str, dict[str, Any], bool]]:
    """The field itself, then (for an object that is not a choice) each of its fields."""
    yield path, prop, required
    target = _single_ref(prop, defs)
    if target is not None and "properties" in target:
        inner_required = set(target.get("required", ()))
        for name, inner in target["properties"].items():
            yield from _flatten(f"{path}.{name}", inner, defs, name in inner_required)


def _single_ref(prop: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any] | None:
    """The one object definition a field refers to (``$ref``, or ``anyOf`` of it and null)."""
    options = prop.get("anyOf", prop.get("oneOf", ()))
    refs = [p["$ref"] for p in [prop, *options] if "$ref" in p]
    if len(refs) != 1 or len(options) > 2:
        return None
    return defs[refs[0].rsplit("/", 1)[-1]]


def _row(path: str, prop: dict[str, Any], required: bool, defs: dict[str, Any]) -> str:
    default = "required" if required else (f"`{_value(prop['default'])}`" if "default" in prop else "")
    description = (prop.get("description") or "").replace("\n", " ").replace("|", "\\|").replace("<", "&lt;")
    return f"| `{path}` | {_type(prop, defs)} | {default} | {_bounds(prop)} | {description} |"


def _value(value: Any) -> str:
    """A default as YAML would show it, floats to 4 significant digits (8.333, not 8.333333333333334)."""
    if isinstance(value, float):
        return f"{value:.4g}"
    return json.dumps(value)


def _type(prop: dict[str, Any], defs: dict[str, Any]) -> str:
    if "const" in prop:
        return f"`{json.dumps(prop['const'])}`"
    if "enum" in prop:
        return " \\| ".join(f"`{v}`" for v in prop["enum"])
    if "$ref" in prop:
        return "object"
    if "anyOf" in prop or "oneOf" in prop:
        return " or ".join(_type(p, defs) for p in prop.get("anyOf", prop.get("oneOf", ())))
    return str(prop.get("type", "any"))


def _bounds(prop: dict[str, Any]) -> str:
    parts = [f"{sign} {_value(prop[key])}" for key, sign in BOUNDS if key in prop]
    for option in prop.get("anyOf", ()):
        parts += [f"{sign} {_value(option[key])}" for key, sign in BOUNDS if key in option]
    return ", ".join(parts)
