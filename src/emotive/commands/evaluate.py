"""``emotive evaluate``: the evaluation suites on any registered model, a checkpoint or a folder.

The models are those of :mod:`emotive.models.registry` (``emotive models``); what each is
judged by follows from its kinds and capabilities (:mod:`emotive.eval.evaluate`). Heavy
modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Annotated, Any

import typer

from emotive.errors import EmotiveError
from emotive.models.registry import REGISTRY

#: The suites of :data:`emotive.eval.evaluate.SUITES`, repeated so that ``--help`` imports no
#: torch (a test checks that the two agree).
SUITE_NAMES: tuple[str, ...] = ("table1", "emotion", "transition", "path", "longrun",
                                "quality", "affect", "speed")


class OptionError(EmotiveError):
    """A ``--option`` that is not ``NAME=VALUE``."""


def parse_options(items: list[str] | None) -> dict[str, Any]:
    """Parse ``name=value`` items into a dict, reading values as Python literals.

    ``["gibbs=20", "root=model"]`` as ``{"gibbs": 20, "root": "model"}``: values that read
    as Python literals (numbers, ``None``, ``True``) become them, the rest stay text.

    Raises:
        OptionError: an item without ``=`` or with an empty name.
    """
    out: dict[str, Any] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise OptionError(f"--option {item!r}: write NAME=VALUE, e.g. --option gibbs=20 "
                              "(see `emotive models` for each model's options)")
        try:
            out[name.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            out[name.strip()] = value.strip()
    return out


def evaluate(
    model: Annotated[
        str, typer.Option("--model", help="A folder of motion files (BVH, glTF, FBX) with "
                          f"intended emotions, a registered model ({', '.join(REGISTRY)}) or a "
                          "gait checkpoint (.pt).", show_default=False)
    ],
    suite: Annotated[
        str, typer.Option("--suite", help=f"{', '.join(SUITE_NAMES)} or all (every suite the "
                          "model supports).")
    ] = "all",
    out: Annotated[Path | None, typer.Option("--out", help="Report folder (default: "
                                             "reports/MODEL).", show_default=False)] = None,
    classifier: Annotated[
        Path | None, typer.Option("--classifier", help="Classifier file (default: built-in).",
                                  show_default=False),
    ] = None,
    weights: Annotated[
        Path | None, typer.Option("--weights", help="Checkpoint (or MAR index) of the model "
                                  "instead of its default.", show_default=False),
    ] = None,
    option: Annotated[
        list[str] | None, typer.Option("--option", help="A model option NAME=VALUE, e.g. "
                                       "gibbs=20 (repeatable; see `emotive models`).",
                                       show_default=False),
    ] = None,
    seconds: Annotated[
        float, typer.Option("--seconds", help="Length of each standard request to a "
                            "generator.", min=1.0, max=3600.0)
    ] = 10.0,
) -> None:
    """Evaluate a model or a folder of BVH files: report.md, metrics.json and plots.

    The table1 suite also prints its tables (per data set, pooled, and by horizon).
    """
    from rich.console import Console

    from emotive.eval.classifier import EmotionClassifier, load_default_classifier
    from emotive.eval.evaluate import resolve_subject, run_suites
    from emotive.eval.report import write_report
    from emotive.eval.sources import standard_requests
    from emotive.io.outputs import check_output_folder

    if out is not None:
        check_output_folder(out, "--out")
    clf = EmotionClassifier.load(classifier) if classifier else None
    subject = resolve_subject(model, (clf or load_default_classifier()).labels, weights,
                              **parse_options(option))
    clf = clf or subject.classifier or load_default_classifier()
    if out is None:
        out = Path("reports") / subject.name
        check_output_folder(out, "--out")
    # A bar only on a terminal: elsewhere it leaves a blank line before the messages.
    results, info = run_suites(subject, suite, clf,
                               progress=Console(stderr=True).is_terminal,
                               requests=standard_requests(clf.labels, seconds))
    folder = write_report(out, subject.name, results, info)
    # The prediction tables are short and are what a user runs this suite for: on the terminal.
    if "table1" in results:
        Console().print(results["table1"]["markdown"], markup=False, highlight=False,
                        soft_wrap=True)
    Console(stderr=True).print(f"wrote {folder / 'report.md'}, {folder / 'metrics.json'} and "
                               f"{sum(len(r.get('figures', [])) for r in results.values())} plots")
