"""``emotive evaluate``: run the suites on a model, a generator or a folder of BVH files.

What can be evaluated (:func:`resolve_subject`):

* a folder of BVH files with intended emotions (:func:`emotive.eval.sources.read_folder`);
* a motion predictor by name (:data:`PREDICTORS`: the zero-velocity baseline);
* a model by name (:data:`MODELS`: the pretrained gait network, its two ablations and the
  QuaterNet baseline) or a gait checkpoint file: predictors for Table 1, and for the gait
  network a generator (:class:`~emotive.eval.sources.Generator`) asked for the standard
  requests.

Suites (:data:`SUITES`) declare what they need: motions with intended emotions (``emotion``,
``transition``, ``path``, ``longrun``, ``quality``, ``affect``), a predictor (``table1``) or a
generator (``speed``). ``all`` runs every suite the subject supports.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from emotive.data.emotion import ALL_LABELS, DEFAULT_LABELS
from emotive.errors import EmotiveError
from emotive.eval import suites
from emotive.eval.classifier import EmotionClassifier, load_default_classifier
from emotive.eval.sources import (
    EvaluatedMotion,
    GenerationRequest,
    Generator,
    from_generator,
    read_folder,
    standard_requests,
)
from emotive.eval.table1 import Predictor, ZeroVelocity


class EvaluationError(EmotiveError):
    """A model or suite that cannot be evaluated as asked."""


#: Predictors by name.
PREDICTORS: dict[str, Callable[[], Predictor]] = {"zero-velocity": ZeroVelocity}


@dataclass
class Subject:
    """What is evaluated: motions, a predictor, a generator, or a predictor and a generator.

    Attributes:
        name: for the report.
        read_motions: produces the motions with their intended emotion.
        predictor: a motion predictor (Table 1).
        generator: a generator (all motion suites and speed).
    """

    name: str
    read_motions: Callable[[], list[EvaluatedMotion]] | None = None
    predictor: Predictor | None = None
    generator: Generator | None = None

    def provides(self) -> set[str]:
        """``"motions"``, ``"predictor"`` and/or ``"generator"``."""
        out = set()
        if self.read_motions is not None or self.generator is not None:
            out.add("motions")
        if self.predictor is not None:
            out.add("predictor")
        if self.generator is not None:
            out.add("generator")
        return out


def gait_subject(checkpoint: str | Path | None = None) -> Subject:
    """The gait network of a checkpoint (default: the pretrained one) as a predictor (Table 1)
    and a generator (every motion suite and speed)."""
    from emotive.models.gait.generate import NetworkGenerator
    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.predict import GaitPredictor

    model = load_gait_model(checkpoint)
    name = "emotive-gait" if checkpoint is None else Path(checkpoint).stem
    return Subject(name, predictor=GaitPredictor(model, name="Ours"),
                   generator=NetworkGenerator(model, name=name))


def quaternet_subject(checkpoint: str | Path | None = None) -> Subject:
    """The QuaterNet baseline of a checkpoint (default: the committed one) as a predictor."""
    from emotive.models.gait.controls import GaitControls
    from emotive.models.gait.predict import QuaterNetPredictor
    from emotive.models.quaternet.training import load_quaternet_checkpoint

    path = Path(checkpoint) if checkpoint is not None else baseline_path("quaternet")
    network, ckpt = load_quaternet_checkpoint(path)
    return Subject("quaternet", predictor=QuaterNetPredictor(
        network, GaitControls.from_dict(ckpt["controls"])))


def baseline_path(name: str) -> Path:
    """A committed baseline or ablation checkpoint, ``emotive/assets/gait/<name>.pt``."""
    from emotive.models.gait.model import default_checkpoint_path

    return default_checkpoint_path().with_name(f"{name}.pt")


#: Subjects by name, beyond :data:`PREDICTORS`: the pretrained gait network, its ablations and
#: the QuaterNet baseline (committed checkpoints).
MODELS: dict[str, Callable[[], Subject]] = {
    "emotive-gait": gait_subject,
    "gait-no-affective": lambda: gait_subject(baseline_path("gait-no-affective")),
    "gait-no-root-loss": lambda: gait_subject(baseline_path("gait-no-root-loss")),
    "quaternet": quaternet_subject,
}


def resolve_subject(spec: str | Path, labels: tuple[str, ...] = DEFAULT_LABELS) -> Subject:
    """A folder of BVH files, a registered model or predictor name (:data:`MODELS`,
    :data:`PREDICTORS`), or a gait checkpoint file (``.pt``).

    Raises:
        EvaluationError: none of these.
    """
    text = str(spec)
    if Path(text).is_dir():
        return Subject(Path(text).name or text, read_motions=lambda: read_folder(text, labels))
    if text in PREDICTORS:
        return Subject(text, predictor=PREDICTORS[text]())
    if text in MODELS:
        return MODELS[text]()
    if text.endswith(".pt"):
        return gait_subject(text)
    raise EvaluationError(
        f"cannot evaluate {text!r}: give a folder of BVH files (with labels.json or Bandai "
        f"file names), a gait checkpoint (.pt) or one of the models "
        f"{', '.join([*MODELS, *PREDICTORS])}"
    )


@dataclass
class Context:
    """What the suites share: the classifier, the real reference and the motions."""

    subject: Subject
    classifier: EmotionClassifier
    requests: list[GenerationRequest] = field(default_factory=list)
    _motions: list[EvaluatedMotion] | None = None
    _reference: suites.RealReference | None = None
    _reference_error: str | None = None

    @property
    def motions(self) -> list[EvaluatedMotion]:
        if self._motions is None:
            if self.subject.generator is not None:
                self._motions = from_generator(self.subject.generator, self.requests)
            else:
                assert self.subject.read_motions is not None
                self._motions = self.subject.read_motions()
        return self._motions

    @property
    def reference(self) -> suites.RealReference | None:
        """Real-motion statistics, or ``None`` (with the reason noted) without the data."""
        if self._reference is None and self._reference_error is None:
            try:
                self._reference = suites.real_reference(self.classifier.labels)
            except EmotiveError as exc:
                self._reference_error = str(exc)
        return self._reference


def _table1(ctx: Context) -> dict:
    from emotive.data.clips import load_clips
    from emotive.data.splits import split_clips
    from emotive.eval.table1 import table1

    assert ctx.subject.predictor is not None
    # Every style is a label here: the four emotions alone leave two test clips long enough
    # for the paper's 6-second windows.
    test = split_clips(load_clips("bandai-namco-1", locomotion=True))["test"]
    rows = {}
    for fps in (10.0, 30.0):
        result = table1([ctx.subject.predictor], test, fps=fps, labels=ALL_LABELS)
        rows[f"{fps:g} fps"] = result
    return {
        "markdown": "\n\n".join(f"At {key}:\n\n{result.to_markdown()}"
                                for key, result in rows.items()),
        "results": {key: result.to_dict() for key, result in rows.items()},
        "reference": f"bandai-namco-1 locomotion test clips, all styles ({len(test)} clips; "
                     "1.8 s primer, 4.2 s predicted, a window every second)",
    }


def _speed(ctx: Context) -> dict:
    """Agent-frames per second of the generator's ``generate`` (one agent at a time)."""
    generator = ctx.subject.generator
    assert generator is not None
    rows = []
    for agents in (1, 10):
        requests = [ctx.requests[k % len(ctx.requests)] for k in range(agents)]
        start = time.perf_counter()
        frames = sum(generator.generate(r).num_frames for r in requests)
        seconds = time.perf_counter() - start
        rows.append({"agents": agents, "frames": frames, "seconds": seconds,
                     "agent_frames_per_second": frames / seconds})
    return {"rows": rows}


#: Suite name -> (what it needs, runner).
SUITES: dict[str, tuple[str, Callable[[Context], dict]]] = {
    "table1": ("predictor", _table1),
    "emotion": ("motions", lambda ctx: suites.emotion_suite(ctx.motions, ctx.classifier)),
    "transition": ("motions", lambda ctx: suites.transition_suite(ctx.motions, ctx.classifier,
                                                                  ctx.reference)),
    "path": ("motions", lambda ctx: suites.path_suite(ctx.motions)),
    "longrun": ("motions", lambda ctx: suites.longrun_suite(ctx.motions, ctx.reference)),
    "quality": ("motions", lambda ctx: suites.quality_suite(ctx.motions, ctx.reference)),
    "affect": ("motions", lambda ctx: suites.affect_suite(ctx.motions, ctx.reference)),
    "speed": ("generator", _speed),
}


def run_suites(subject: Subject, suite: str, classifier: EmotionClassifier | None = None,
               progress: bool = False, requests: list[GenerationRequest] | None = None,
               ) -> tuple[dict[str, dict], dict]:
    """Run one suite or ``"all"`` on a subject.

    ``requests`` replace :func:`~emotive.eval.sources.standard_requests` for a generator.

    Returns:
        ``(suite name -> result, facts for the report)``.

    Raises:
        EvaluationError: unknown suite, or one the subject cannot be judged by.
    """
    from rich.console import Console
    from rich.progress import track

    if suite != "all" and suite not in SUITES:
        raise EvaluationError(f"unknown suite {suite!r}: use one of {', '.join(SUITES)} or all")
    provided = subject.provides()
    names = [s for s, (need, _) in SUITES.items() if need in provided] if suite == "all" else [
        suite]
    need = SUITES[names[0]][0] if names else None
    if not names or need not in provided:
        raise EvaluationError(
            f"suite {suite!r} needs a {need or 'model'}, and {subject.name} provides "
            f"{', '.join(sorted(provided)) or 'nothing'}; suites it supports: "
            f"{', '.join(s for s, (n, _) in SUITES.items() if n in provided)}"
        )
    classifier = classifier or load_default_classifier()
    ctx = Context(subject, classifier,
                  requests if requests is not None else standard_requests(classifier.labels))
    results = {}
    for name in track(names, description="evaluating", disable=not progress,
                      console=Console(stderr=True), transient=True):
        results[name] = SUITES[name][1](ctx)
    real = classifier.metrics.get("test", {}).get("window_accuracy", float("nan"))
    info = {
        "model": subject.name,
        "suites": ", ".join(names),
        "classifier": f"{', '.join(classifier.labels)}; real held-out window accuracy {real:.3f}",
    }
    if ctx._reference_error:
        info["real reference"] = f"unavailable ({ctx._reference_error})"
    return results, info
