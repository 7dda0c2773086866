"""Alembic environment of the study database: runs on the connection the caller opened.

:func:`emotive.study.db.migrate` passes its connection in ``config.attributes``; there is no
``alembic.ini`` and no URL here.
"""

from alembic import context

from emotive.study.db import metadata

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=metadata,
                  render_as_batch=connection.dialect.name == "sqlite")
with context.begin_transaction():
    context.run_migrations()
