"""The first study schema: meta, participants, submissions, responses.

Revision ID: 0001
Revises:
Create Date: 2026-12-04
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Create the four tables."""
    op.create_table(
        "study_meta",
        sa.Column("key", sa.String(64), primary_key=True),
        sa.Column("value", sa.Text, nullable=False),
    )
    op.create_table(
        "participants",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("public_id", sa.String(32), nullable=False, unique=True),
        sa.Column("token_hash", sa.String(64), nullable=False, unique=True),
        sa.Column("join_index", sa.Integer, nullable=False, unique=True),
        sa.Column("condition", sa.String(64), nullable=False),
        sa.Column("plan", sa.Text, nullable=False),
        sa.Column("joined_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("completed_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("excluded", sa.Boolean, nullable=False),
        sa.Column("exclusion_reason", sa.String(500), nullable=False),
    )
    op.create_table(
        "submissions",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("participant_id", sa.Integer, sa.ForeignKey("participants.id"),
                  nullable=False),
        sa.Column("item", sa.Integer, nullable=False),
        sa.Column("idempotency_key", sa.String(128), nullable=False),
        sa.Column("body_hash", sa.String(64), nullable=False),
        sa.Column("rt_ms", sa.Integer, nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("participant_id", "item", name="uq_submission_item"),
        sa.UniqueConstraint("participant_id", "idempotency_key", name="uq_submission_key"),
    )
    op.create_table(
        "responses",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("submission_id", sa.Integer, sa.ForeignKey("submissions.id"),
                  nullable=False),
        sa.Column("participant_id", sa.Integer, sa.ForeignKey("participants.id"),
                  nullable=False),
        sa.Column("item", sa.Integer, nullable=False),
        sa.Column("stimulus", sa.String(64), nullable=False),
        sa.Column("question", sa.String(64), nullable=False),
        sa.Column("value_num", sa.Float, nullable=True),
        sa.Column("value_text", sa.String(200), nullable=True),
        sa.UniqueConstraint("participant_id", "item", "question",
                            name="uq_response_question"),
    )


def downgrade() -> None:
    """Drop the four tables."""
    for table in ("responses", "submissions", "participants", "study_meta"):
        op.drop_table(table)
