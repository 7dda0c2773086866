"""CLI sub-commands, one module per group; registered in :mod:`emotive.cli`."""
