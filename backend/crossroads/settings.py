"""Settings of the running service, from the command line or CROSSROADS_* environment variables.

Fails fast: a bad value is an error naming the setting when the service starts, not later.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

DEFAULT_DATA_DIR = Path.home() / ".local" / "share" / "crossroads"
SUPPORTED_DB_SCHEMES = ("sqlite", "postgresql")


class Settings(BaseSettings):
    """Where the studio listens and where it keeps its data."""

    model_config = SettingsConfigDict(env_prefix="CROSSROADS_", extra="forbid", frozen=True)

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

    @property
    def database_url(self) -> str:
        return self.db_url or f"sqlite:///{self.data_dir / 'crossroads.db'}"
