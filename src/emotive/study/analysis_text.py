"""Markdown of the study report: tables, numbers, p-values and the statistics not computed.

Helpers of :mod:`emotive.study.analyze`. A statistic that cannot be computed on the data (too
few raters, constant ratings, one condition) is one line of the report saying why
(:meth:`Section.skip`, :func:`attempt`), never an exception.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from emotive.eval.stats import MissingDependencyError, StatsInputError

T = TypeVar("T")


def fmt(value: float | None, digits: int = 3) -> str:
    """A number with ``digits`` decimals; ``n/a`` for ``None`` and NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def fmt_p(p: float, bounded: bool = False) -> str:
    """A p-value: ``< 0.001`` below it, ``> 0.25`` at the Anderson-Darling table's upper bound.

    Args:
        p: the p-value.
        bounded: the p-value lies at a bound of an interpolated table (SciPy's
            Anderson-Darling p-values are capped to [0.001, 0.25]).
    """
    if math.isnan(p):
        return "n/a"
    if bounded and p >= 0.25:
        return "> 0.25"
    if p < 0.001:
        return "< 0.001"
    return f"{p:.3f}"


def pct(share: float | None) -> str:
    """A share in [0, 1] as a whole percentage (``n/a`` for ``None`` or NaN)."""
    if share is None or math.isnan(share):
        return "n/a"
    return f"{100.0 * share:.0f}%"


#: A cell that reads as a number: ``0.25``, ``-1.6``, ``> 0.25``, ``**85%**``, ``84% (32)``.
_NUMERIC = re.compile(r"^\**(?:[<>]\s)?-?\d")


def _right(cells: Sequence[str]) -> bool:
    """Whether a column is numbers (right-aligned): every cell a number, ``-`` or ``n/a``."""
    filled = [c for c in cells if c not in ("", "-", "n/a")]
    return bool(filled) and all(_NUMERIC.match(c) for c in filled)


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """A markdown table, number columns right-aligned, ending with a blank line.

    Pipes in cells are escaped so that they do not split a cell.
    """
    text = [[str(c).replace("|", "\\|") for c in row] for row in rows]
    rule = ["---:" if _right([row[i] for row in text]) else "---"
            for i in range(len(headers))]
    out = ["| " + " | ".join(str(h).replace("|", "\\|") for h in headers) + " |",
           "| " + " | ".join(rule) + " |"]
    out += ["| " + " | ".join(row) + " |" for row in text]
    return [*out, ""]


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 rater``, ``2 raters`` (``many``: the plural when it is not ``word + "s"``)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


def one_line(text: str) -> str:
    """A message as one markdown line (newlines and pipes removed)."""
    return " ".join(str(text).split()).replace("|", "/")


@dataclass
class Section:
    """One section of the report, as it is written.

    Attributes:
        title: its heading.
        lines: the markdown lines below the heading.
        skipped: ``"what: why"`` of each statistic that could not be computed.
        plots: the PNG files it drew (paths in the output folder).
    """

    title: str
    lines: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    plots: list[Path] = field(default_factory=list)

    def add(self, *lines: str) -> None:
        """Append markdown lines."""
        self.lines.extend(lines)

    def skip(self, what: str, why: str) -> None:
        """Say on one line why the statistic ``what`` was not computed."""
        why = one_line(why).rstrip(".")
        self.lines.append(f"- *{what}*: not computed: {why}.")
        self.skipped.append(f"{what}: {why}")

    def markdown(self) -> list[str]:
        """The heading and the lines, ending with a blank line."""
        body = list(self.lines)
        if body and body[-1] != "":
            body.append("")
        return [f"## {self.title}", "", *body]


def attempt(section: Section, what: str, fn: Callable[..., T], *args: Any, **kwargs: Any
            ) -> T | None:
    """``fn(*args, **kwargs)``, or ``None`` with a line in ``section`` saying why it failed.

    Catches the input errors of :mod:`emotive.eval.stats` (and a missing optional library),
    and the ``ValueError`` or arithmetic errors the libraries raise on degenerate data that
    the input checks let through; SciPy's and pingouin's RuntimeWarnings on such data are
    silenced, as the report states the reason instead.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return fn(*args, **kwargs)
    except (StatsInputError, MissingDependencyError) as exc:
        section.skip(what, str(exc))
    except (ValueError, ArithmeticError) as exc:  # numpy's LinAlgError is a ValueError
        section.skip(what, f"the statistics library failed on this data ({exc})")
    return None

