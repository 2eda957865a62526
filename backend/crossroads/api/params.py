"""Path and query parameters shared by the routes: ids bounded by their columns, and pagination.

Every id of the store is an INTEGER column (32-bit on PostgreSQL, :data:`MAX_ROW_ID`): an id
beyond it is a 422 naming the parameter before any query runs, never a database error. Every list
is paged (``limit`` with a maximum, ``offset``) and says its full length in ``X-Total-Count``.
"""

# No ``from __future__ import annotations``: the page dependency's annotations name its local bounds,
# and FastAPI must read them as objects, not strings.

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, TypeVar

from fastapi import Path, Query, Response

from crossroads.store.tables import MAX_ROW_ID

TOTAL_HEADER = "X-Total-Count"
T = TypeVar("T")
MAX_OFFSET = MAX_ROW_ID

BatchId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="id of a batch")]
ScenarioId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="id of a scenario")]
RunIndex = Annotated[int, Path(ge=0, le=MAX_ROW_ID, description="run index within the batch (0-based)")]
LiveId = Annotated[int, Path(ge=1, le=MAX_ROW_ID, description="id of a live run")]


@dataclass(frozen=True)
class Page:
    """One page of a list: at most ``limit`` items from ``offset`` on."""

    limit: int
    offset: int

    def slice(self, items: list[T], response: Response) -> list[T]:
        """This page of an in-memory list, its length in the total header."""
        response.headers[TOTAL_HEADER] = str(len(items))
        return items[self.offset:self.offset + self.limit]


def paging(default: int, maximum: int) -> Callable[..., Page]:
    """A dependency reading ``limit`` (1..``maximum``, default ``default``) and ``offset``."""

    def page(limit: Annotated[int, Query(ge=1, le=maximum, description=f"items per page (at most {maximum})")] = default,
             offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description="items to skip")] = 0) -> Page:
        return Page(limit, offset)

    return page


def set_total(response: Response, total: int) -> None:
    response.headers[TOTAL_HEADER] = str(total)
