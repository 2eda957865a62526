"""Every ``CROSSROADS_*`` environment variable Crossroads reads, and the service's settings.

:class:`Settings`: the running service's settings, from the command line or ``CROSSROADS_*``
variables; it fails fast: a bad value is an error naming the setting when the service starts, not
later. The library's own variables, read when they are needed (a test or a worker may set them):

* ``CROSSROADS_CACHE_DIR``: where built intersections are cached (:func:`net_cache_dir`);
* ``CROSSROADS_SCENARIOS_DIR``: the root of the scenario files and the catalogue (:func:`scenarios_dir`);
* ``CROSSROADS_FRONTEND_DIST``: the studio page's build the API serves (:func:`frontend_dist_dir`);
* ``CROSSROADS_FORK_EPISODES=0``: batch workers run each episode themselves instead of in a forked
  child (:func:`fork_episodes`).
"""

from __future__ import annotations

import ipaddress
import os
import re
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

ENV_PREFIX = "CROSSROADS_"
REPOSITORY_ROOT = Path(__file__).resolve().parents[2]  # this file: <repo>/backend/crossroads/settings.py
DEFAULT_DATA_DIR = Path.home() / ".local" / "share" / "crossroads"
SUPPORTED_DB_SCHEMES = ("sqlite", "postgresql")
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")  # what a browser on this machine calls it
WILDCARD_HOSTS = ("0.0.0.0", "::", "")  # listen on every interface
MAX_BATCH_WORKERS = 64  # worker processes of one batch, at most (each holds a SUMO and ~130 MB)
MIN_TOKEN_CHARS = 16
TOKEN_CHARS = re.compile(r"[A-Za-z0-9._~-]+")


def host_name(host: str) -> str:
    """``[::1]`` → ``::1``; ``LocalHost.`` → ``localhost``: the comparable form of a host name."""
    name = host.strip().lower()
    if name.startswith("[") and name.endswith("]"):
        name = name[1:-1]
    return name.rstrip(".")


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) only reaches this machine."""
    name = host_name(host)
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def _default_workers() -> int:
    return max(1, min(os.cpu_count() or 1, MAX_BATCH_WORKERS))


class Settings(BaseSettings):
    """Where the studio listens and where it keeps its data."""

    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, extra="forbid", frozen=True)

    host: str = Field("127.0.0.1", description="interface the API listens on")
    port: int = Field(8000, ge=1, le=65535, description="TCP port of the API")
    data_dir: Path = Field(DEFAULT_DATA_DIR, description="traces, uploads and the SQLite database")
    db_url: str | None = Field(
        None, description="SQLAlchemy URL of the results store; default: SQLite in data_dir"
    )
    ray_address: str | None = Field(None, description="Ray cluster for batches; default: local workers")
    max_concurrent_batches: int = Field(
        2, ge=1, le=64,
        description="batches the API runs at once; a batch started beyond that waits in a queue",
    )
    resume_batches: bool = Field(
        True,
        description="at start, resume the batches a previous API process left queued or running "
        "(turn off when another process, e.g. `crossroads evaluate`, runs batches of the same store)",
    )
    token: SecretStr | None = Field(
        None, min_length=MIN_TOKEN_CHARS,
        description="access token every request must carry when the API listens beyond this machine "
        "(`Authorization: Bearer <token>`, or the cookie the page gets from `/?token=<token>`); "
        "`crossroads serve` generates one when none is given",
    )
    allowed_hosts: Annotated[tuple[str, ...], NoDecode] = Field(
        (), description="host names (or addresses) the API answers to besides localhost and the "
        "interface it listens on: the names a browser uses to reach it (comma-separated in the "
        "environment; '*' answers to any, leaving only the token against DNS rebinding)",
    )
    max_batch_workers: int = Field(
        default_factory=_default_workers, ge=1, le=MAX_BATCH_WORKERS,
        description="most worker processes one batch may ask for (default: one per CPU)",
    )
    episode_wall_limit_s: float = Field(
        900.0, gt=0.0, le=86_400.0,
        description="[s] wall-clock time one episode of a batch may take, counted from when it is "
        "handed to its worker (a fresh worker's start-up included); beyond it the episode is stopped "
        "(its worker killed) and recorded as an error ('wall-clock limit')",
    )
    json_body_max_bytes: int = Field(
        1 << 20, ge=1024, le=64 << 20,
        description="[bytes] largest request body the API reads, except network uploads (their own limit)",
    )

    @field_validator("db_url")
    @classmethod
    def _known_database(cls, url: str | None) -> str | None:
        if url is None:
            return None
        scheme = url.split(":", 1)[0].split("+", 1)[0]
        if "://" not in url or scheme not in SUPPORTED_DB_SCHEMES:
            raise ValueError(
                f"{url!r} is not a database URL Crossroads supports; "
                "use sqlite:///PATH or postgresql://USER@HOST:PORT/DB"
            )
        return url

    @field_validator("token")
    @classmethod
    def _token_chars(cls, token: SecretStr | None) -> SecretStr | None:
        # it travels in a header, a cookie and a URL: printable ASCII, none of their delimiters
        if token is not None and not TOKEN_CHARS.fullmatch(token.get_secret_value()):
            raise ValueError("use letters, digits and - . _ ~ only")
        return token

    @field_validator("allowed_hosts", mode="before")
    @classmethod
    def _host_list(cls, value: Any) -> Any:
        if isinstance(value, str):  # CROSSROADS_ALLOWED_HOSTS=studio.lan,192.168.1.5
            value = [part for part in value.split(",") if part.strip()]
        if isinstance(value, list | tuple):
            names = tuple(host_name(str(v)) for v in value)
            bad = [n for n in names if not n or any(c in n for c in "/ @?#")]
            if bad:
                raise ValueError(f"not a host name: {bad[0]!r}")
            return names
        return value

    @property
    def database_url(self) -> str:
        return self.db_url or f"sqlite:///{self.data_dir / 'crossroads.db'}"

    @property
    def public(self) -> bool:
        """Whether the API listens beyond this machine (then it needs a token)."""
        return not is_loopback(self.host)

    def answered_hosts(self) -> frozenset[str]:
        """The host names (``Host`` header, port left out) the API answers to."""
        names = {host_name(n) for n in LOOPBACK_NAMES} | set(self.allowed_hosts)
        if host_name(self.host) not in WILDCARD_HOSTS:
            names.add(host_name(self.host))
        return frozenset(names)


# --- the library's environment -----------------------------------------------------------------


def net_cache_dir() -> Path:
    """Directory holding cached intersection builds: ``$CROSSROADS_CACHE_DIR`` or ``~/.cache/crossroads/nets``."""
    env = os.environ.get(f"{ENV_PREFIX}CACHE_DIR")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "crossroads" / "nets"


def scenarios_dir() -> Path:
    """Root of the scenario files: ``$CROSSROADS_SCENARIOS_DIR`` or ``<repo>/scenarios``."""
    env = os.environ.get(f"{ENV_PREFIX}SCENARIOS_DIR")
    return Path(env).expanduser() if env else REPOSITORY_ROOT / "scenarios"


def frontend_dist_dir() -> Path:
    """The studio page's build: ``$CROSSROADS_FRONTEND_DIST`` or ``<repo>/frontend/dist``."""
    configured = os.environ.get(f"{ENV_PREFIX}FRONTEND_DIST")
    return Path(configured) if configured else REPOSITORY_ROOT / "frontend" / "dist"


def fork_episodes() -> bool:
    """Whether batch workers fork a child per episode where the platform can (unless
    ``CROSSROADS_FORK_EPISODES=0``; see ``crossroads.evaluation.executors``)."""
    return os.environ.get(f"{ENV_PREFIX}FORK_EPISODES", "1") != "0"
