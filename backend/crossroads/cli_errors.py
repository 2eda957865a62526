"""How the command line reports bad input: one red line on stderr, exit status 2.

Shared by ``crossroads`` (:mod:`crossroads.cli`) and ``crossroads train`` (:mod:`crossroads.rl.cli`).
"""

from __future__ import annotations

import typer


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``error: message`` in red on stderr; raise the returned Exit (status 2: bad input)."""
    typer.secho(f"error: {message}", err=True, fg=typer.colors.RED)
    return typer.Exit(code=code)


def describe(exc: BaseException) -> str:
    """One line for an error: pydantic's validation errors as ``field.path: message; ...``
    (its own text spreads them over several lines), anything else as its text."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        return "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())
    return str(exc)
