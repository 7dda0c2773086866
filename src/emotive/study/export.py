"""``emotive study export``: every stored response as CSV, one row per value.

Columns (:data:`emotive.study.store.EXPORT_COLUMNS`): ``participant`` (random id),
``condition``, ``stimulus``, ``question``, ``value`` (likert integers, grid values on -1..1
as ``valence`` and ``arousal``, choice texts), ``time`` (the submission's, UTC, ISO 8601),
then ``item``, ``repeat`` (0: first rating, 1: second pass), ``check`` (the attention check's
id, or empty), ``source`` and ``intended`` of the stimulus, ``rt_ms`` (response time) and
``excluded`` (1 when the admin excluded the participant).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from sqlalchemy.engine import Engine

from emotive.io.atomic import atomic_output
from emotive.study import store
from emotive.study.config import StudyConfig
from emotive.study.db import open_database


def export_csv(engine: Engine, study: StudyConfig) -> str:
    """The export as CSV text."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=store.EXPORT_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(store.export_rows(engine, study))
    return out.getvalue()


def write_export(study: StudyConfig, db_url: str | None, out: Path) -> int:
    """Write the export of a study's database to ``out`` (atomically).

    Returns:
        The number of rows written.

    Raises:
        StudyError: the database cannot be opened or holds another design.
    """
    engine = open_database(study.folder, db_url, pool_size=1)
    try:
        store.check_design(engine, study)
        text = export_csv(engine, study)
    finally:
        engine.dispose()
    with atomic_output(out) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return text.count("\n") - 1
