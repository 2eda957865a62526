"""The results store: scenarios, policies, batches, episodes and traces (SQLAlchemy 2 + Alembic).

    store = open_store("sqlite:///results.db")        # or postgresql+psycopg://..., migrated
    with store.session() as session:
        batch = crud.get_batch(session=session, batch_id=3)
"""

from crossroads.store.db import Store, StoreError, open_store
from crossroads.store import search_tables  # noqa: F401  (its tables join the metadata)

__all__ = ["Store", "StoreError", "open_store"]
