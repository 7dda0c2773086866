"""``emotive evaluate``: the evaluation suites on any registered model, a checkpoint or a folder.

The models are those of :mod:`emotive.models.registry` (``emotive models``); what each is
judged by follows from its kinds and capabilities (:mod:`emotive.eval.evaluate`). Heavy
modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import ast
import difflib
import os
from pathlib import Path
from typing import Annotated, Any

import typer

from emotive.commands.options import ForceOpt, input_file
from emotive.errors import ConfigError, EmotiveError
from emotive.io.outputs import check_output_folder, existing_output
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


#: The files of a report; a folder holding one of them holds a report (replaced with --force).
REPORT_FILES = ("report.md", "metrics.json")


def check_subject(model: str) -> None:
    """Fail fast on a ``--model`` that is no registered model, folder or checkpoint.

    Raises:
        ConfigError: naming the value, what it was taken for and the fix (``does not exist``
            for a folder or checkpoint that is not there).
    """
    path = Path(model)
    if model in REGISTRY or path.is_dir():
        return
    models = f"one of the models {', '.join(REGISTRY)} (see `emotive models`)"
    if model.endswith(".pt"):
        if not path.is_file():
            raise ConfigError(f"--model {model}: the checkpoint does not exist; check the path")
        return
    if path.exists():
        raise ConfigError(f"--model {model} is a file, not a folder of motion files or a .pt "
                          f"checkpoint; give a folder, a checkpoint or {models}")
    if model.endswith(("/", os.sep)) or os.sep in model or "/" in model:
        raise ConfigError(f"--model {model}: the folder does not exist; check the path, or give "
                          f"a gait checkpoint (.pt) or {models}")
    close = difflib.get_close_matches(model, list(REGISTRY), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise ConfigError(f"--model {model!r}: no model has that name{hint} and no folder of that "
                      f"name exists; give {models}, a folder of motion files or a .pt "
                      "checkpoint")


def report_folder(out: Path, force: bool) -> None:
    """The output rule for a report folder: checked, and one holding a report needs --force.

    Raises:
        OutputError: a folder that cannot take the report, or one that holds a report
            (``report.md`` or ``metrics.json``) without ``force``.
    """
    check_output_folder(out, "--out")
    for name in REPORT_FILES:
        existing_output(out / name, "--out", force)


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
                                             "reports/MODEL); one holding a report is "
                                             "replaced only with --force.",
                                             show_default=False)] = None,
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
    force: ForceOpt = False,
) -> None:
    """Evaluate a model or a folder of BVH files: report.md, metrics.json and plots.

    The table1 suite also prints its tables (per data set, pooled, and by horizon).
    """
    if suite not in (*SUITE_NAMES, "all"):
        close = difflib.get_close_matches(suite, SUITE_NAMES, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"--suite {suite!r}: no suite has that name{hint}; give one of "
                          f"{', '.join(SUITE_NAMES)} or all")
    if out is not None:
        report_folder(out, force)
    check_subject(model)
    for flag_name, file in (("--classifier", classifier), ("--weights", weights)):
        if file is not None:
            input_file(file, flag_name, None, ConfigError)
    options = parse_options(option)

    from rich.console import Console

    from emotive.eval.classifier import EmotionClassifier, load_default_classifier
    from emotive.eval.evaluate import resolve_subject, run_suites
    from emotive.eval.report import write_report
    from emotive.eval.sources import standard_requests

    clf = EmotionClassifier.load(classifier) if classifier else None
    subject = resolve_subject(model, (clf or load_default_classifier()).labels, weights,
                              **options)
    clf = clf or subject.classifier or load_default_classifier()
    if out is None:
        out = Path("reports") / subject.name
        report_folder(out, force)
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
