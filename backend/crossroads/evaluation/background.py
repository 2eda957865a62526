"""A job that runs where it is called (:meth:`run`) or in a background thread (:meth:`start`,
then :meth:`wait`), and can be cancelled from any thread: what a batch and a failure search share."""

from __future__ import annotations

import threading
from typing import Generic, TypeVar

S = TypeVar("S")  # what a finished job sums up to


class BackgroundJob(Generic[S]):
    """Subclasses implement :meth:`run` (it sets ``self._summary``) and name themselves in
    ``_thread_name``; errors of this base are raised as ``_error_type``."""

    _error_type: type[Exception] = RuntimeError

    def __init__(self, thread_name: str) -> None:
        self._thread_name = thread_name
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None
        self._exception: BaseException | None = None
        self._summary: S | None = None

    def run(self) -> object:
        raise NotImplementedError

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    @property
    def running(self) -> bool:
        """Started in the background and not finished yet."""
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> threading.Thread:
        """Run in a background thread; returns at once."""
        if self._thread is not None:
            raise self._error_type(f"{self._thread_name} was started already")
        self._thread = threading.Thread(target=self._run_in_thread, daemon=True,
                                        name=f"crossroads-{self._thread_name.replace(' ', '-')}")
        self._thread.start()
        return self._thread

    def _run_in_thread(self) -> None:
        try:
            self.run()
        except BaseException as exc:  # noqa: BLE001 - kept for wait()
            self._exception = exc

    def wait(self, timeout: float | None = None) -> S | None:
        """Wait for a started job; its summary (None on timeout). Re-raises its exception."""
        if self._thread is None:
            raise self._error_type(f"{self._thread_name} was not started")
        self._thread.join(timeout)
        if self._thread.is_alive():
            return None
        if self._exception is not None:
            raise self._exception
        return self._summary
