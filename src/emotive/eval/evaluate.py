"""``emotive evaluate``: run the suites on a registered model, a checkpoint or a folder of BVH.

What can be evaluated (:func:`resolve_subject`):

* a folder of BVH files with intended emotions (:func:`emotive.eval.sources.read_folder`);
* any model of the registry (:mod:`emotive.models.registry`, ``emotive models``), by what it
  can be loaded as: a ``predictor`` is judged by Table 1, a ``generator`` by every motion suite
  its :class:`~emotive.models.api.Capabilities` allow (the standard requests of
  :func:`~emotive.eval.sources.standard_requests`, less what it cannot honour:
  :func:`~emotive.eval.sources.requests_for`) and by ``speed``, a ``transfer`` model by the
  motion suites on a few real neutral walks rendered in each label (:func:`transfer_clips`),
  and the ``classifier`` by the emotion suite on real held-out clips (its own accuracy);
* a gait checkpoint file (``.pt``), as the ``gait`` model with those weights.

Suites (:data:`SUITES`) declare what they need (:data:`NEEDS`): motions with intended emotions
(``emotion``, ``longrun``, ``quality``, ``affect``), motions along paths (``path``), motions
whose emotion changes (``transition``), a predictor (``table1``) or a generator (``speed``).
``all`` runs every suite the subject supports.
"""

from __future__ import annotations

import difflib
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import track

from emotive.data.clips import load_clips
from emotive.data.emotion import DEFAULT_LABELS, Emotion, EmotionSchedule
from emotive.data.splits import split_clips
from emotive.errors import EmotiveError
from emotive.eval import suites
from emotive.eval.classifier import EmotionClassifier, load_default_classifier
from emotive.eval.sources import (
    EvaluatedMotion,
    from_generator,
    from_transfer,
    read_folder,
    requests_for,
    standard_requests,
)
from emotive.eval.table1 import ZeroVelocity
from emotive.models.api import GenerationRequest, Generator, Predictor, TransferModel
from emotive.models.registry import REGISTRY, get_model

#: Real neutral walks a transfer model renders in each label (:func:`transfer_clips`).
TRANSFER_CLIPS = 2


class EvaluationError(EmotiveError):
    """A model or suite that cannot be evaluated as asked."""


def load_zero_velocity(name: str = "zero-velocity", weights: None = None) -> ZeroVelocity:
    """Registry loader of ``zero-velocity``.

    The baseline predictor (:class:`~emotive.eval.table1.ZeroVelocity`, named as in Table 1).
    """
    return ZeroVelocity()


def load_classifier(name: str = "classifier", weights: str | Path | None = None
                    ) -> EmotionClassifier:
    """Registry loader of ``classifier``.

    The committed perceived-emotion classifier, or the one of ``weights`` (a file of ``emotive train
    classifier``).
    """
    return EmotionClassifier.load(weights) if weights is not None else load_default_classifier()


@dataclass
class Subject:
    """What is evaluated: motions, a predictor, a generator, or a predictor and a generator.

    Attributes:
        name: for the report.
        read_motions: produces the motions with their intended emotion.
        predictor: a motion predictor (Table 1).
        generator: a generator (the motion suites its capabilities allow, and speed).
        classifier: the judge to use when the caller gives none (the subject of
            ``--model classifier``).
        paths: whether :attr:`read_motions` may hold motions along paths.
        transitions: whether :attr:`read_motions` may hold motions whose emotion changes.
    """

    name: str
    read_motions: Callable[[], list[EvaluatedMotion]] | None = None
    predictor: Predictor | None = None
    generator: Generator | None = None
    classifier: EmotionClassifier | None = None
    paths: bool = True
    transitions: bool = True

    def provides(self) -> set[str]:
        """What the subject offers, among the keys of :data:`NEEDS`."""
        out = set()
        if self.read_motions is not None:
            out.add("motions")
            out |= {"paths"} if self.paths else set()
            out |= {"transitions"} if self.transitions else set()
        if self.generator is not None:
            caps = self.generator.capabilities
            out |= {"motions", "generator"}
            out |= {"paths"} if caps.paths else set()
            out |= {"transitions"} if caps.schedules else set()
        if self.predictor is not None:
            out.add("predictor")
        return out


def transfer_clips(labels: tuple[str, ...], count: int = TRANSFER_CLIPS
                   ) -> list[EvaluatedMotion]:
    """The first ``count`` neutral walks of the held-out test split of ``bandai-namco-1``.

    Raises:
        DataError: the data set is missing.
    """
    test = split_clips(load_clips("bandai-namco-1", locomotion=True))["test"]
    neutral = [c for c in test if c.info.emotion == "neutral"][:count]
    schedule = EmotionSchedule.constant(Emotion.one_hot("neutral", labels))
    return [EvaluatedMotion(c.name, c.motion,
                            schedule.sample(c.motion.fps, num_frames=c.motion.num_frames),
                            labels) for c in neutral]


def transfer_subject(model: TransferModel, labels: tuple[str, ...] = DEFAULT_LABELS,
                     count: int = TRANSFER_CLIPS,
                     clips: Callable[[], list[EvaluatedMotion]] | None = None) -> Subject:
    """A transfer model as motions: clips rendered in each of ``labels``.

    A transfer model as motions: the ``clips`` (default: :func:`transfer_clips`) rendered
    in each of ``labels`` (the labels the model lacks are left out).
    """
    styles = tuple(label for label in labels if label in model.labels)
    read = clips or (lambda: transfer_clips(labels, count))
    return Subject(model.name, paths=False, transitions=False,
                   read_motions=lambda: from_transfer(model, read(), styles))


def held_out_subject(classifier: EmotionClassifier) -> Subject:
    """The classifier judged on the real held-out test clips of its labels."""
    labels = classifier.labels

    def read() -> list[EvaluatedMotion]:
        test = split_clips(load_clips("bandai-namco-1", locomotion=True))["test"]
        out = []
        for clip in test:
            if clip.info.emotion in labels:
                schedule = EmotionSchedule.constant(Emotion.one_hot(clip.info.emotion, labels))
                out.append(EvaluatedMotion(clip.name, clip.motion, schedule.sample(
                    clip.motion.fps, num_frames=clip.motion.num_frames), labels))
        return out

    return Subject("classifier", read_motions=read, classifier=classifier, paths=False,
                   transitions=False)


def model_subject(name: str, labels: tuple[str, ...] = DEFAULT_LABELS,
                  weights: str | Path | None = None, **options: Any) -> Subject:
    """A registered model as a subject, by its kinds.

    A registered model (:data:`~emotive.models.registry.REGISTRY`) as a subject, by its
    kinds (see the module docstring).

    Raises:
        ModelError: an unknown name or option.
    """
    entry = get_model(name)
    label = name if weights is None else Path(weights).stem
    if "classifier" in entry.kinds:
        return held_out_subject(entry.load("classifier", weights, **options))
    if "transfer" in entry.kinds:
        return transfer_subject(entry.load("transfer", weights, **options), labels)
    return Subject(
        label,
        predictor=entry.load("predictor", weights, **options)
        if "predictor" in entry.kinds else None,
        generator=entry.load("generator", weights, **options)
        if "generator" in entry.kinds else None,
    )


def resolve_subject(spec: str | Path, labels: tuple[str, ...] = DEFAULT_LABELS,
                    weights: str | Path | None = None, **options: Any) -> Subject:
    """A folder of BVH files, a registered model name, or a gait checkpoint file (``.pt``).

    Args:
        spec: what to evaluate.
        labels: the labels of the intended emotions (the classifier's).
        weights: weights of a registered model instead of its default.
        **options: model-specific options (see ``emotive models``); ``None`` ones are ignored.

    Raises:
        EvaluationError: none of these.
        ModelError: an option the model does not take.
    """
    text = str(spec)
    if Path(text).is_dir():
        return Subject(Path(text).name or text, read_motions=lambda: read_folder(text, labels))
    if text in REGISTRY:
        return model_subject(text, labels, weights, **options)
    if text.endswith(".pt"):
        return model_subject("gait", labels, text, **options)
    close = difflib.get_close_matches(text, list(REGISTRY), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise EvaluationError(
        f"cannot evaluate {text!r}{hint}: give a folder of BVH files (with labels.json or "
        f"Bandai file names), a gait checkpoint (.pt) or one of the models "
        f"{', '.join(REGISTRY)} (see `emotive models`)"
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
        """The subject's motions, generated or read on first use."""
        if self._motions is None:
            if self.subject.generator is not None:
                requests = requests_for(self.subject.generator.capabilities, self.requests)
                self._motions = from_generator(self.subject.generator, requests)
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
    assert ctx.subject.predictor is not None
    return suites.table1_suite(ctx.subject.predictor)


def _speed(ctx: Context) -> dict:
    """Agent-frames per second of the generator's ``generate``, one request at a time.

    Each row's ``agents`` requests are made one after the other, as an application asking for
    one character's clip at a time makes them, so the rate does not grow with the count; a
    crowd stepped together (:class:`~emotive.models.gait.generate.GaitGenerator`) is measured
    by ``make bench``.
    """
    generator = ctx.subject.generator
    assert generator is not None
    rows = []
    usable = requests_for(generator.capabilities, ctx.requests)
    for agents in (1, 10):
        requests = [usable[k % len(usable)] for k in range(agents)]
        start = time.perf_counter()
        frames = sum(generator.generate(r).motion.num_frames for r in requests)
        seconds = time.perf_counter() - start
        rows.append({"agents": agents, "frames": frames, "seconds": seconds,
                     "agent_frames_per_second": frames / seconds})
    return {"rows": rows}


#: What a suite may need (:meth:`Subject.provides`), in words for messages.
NEEDS: dict[str, str] = {
    "motions": "motions with intended emotions",
    "paths": "motions along paths (a generator that follows paths, or a folder)",
    "transitions": "motions whose emotion changes (a generator of schedules, or a folder)",
    "predictor": "a predictor (a motion-prediction model)",
    "generator": "a generator",
}

#: Suite name -> (what it needs, a key of :data:`NEEDS`; runner).
SUITES: dict[str, tuple[str, Callable[[Context], dict]]] = {
    "table1": ("predictor", _table1),
    "emotion": ("motions", lambda ctx: suites.emotion_suite(ctx.motions, ctx.classifier)),
    "transition": ("transitions", lambda ctx: suites.transition_suite(
        ctx.motions, ctx.classifier, ctx.reference)),
    "path": ("paths", lambda ctx: suites.path_suite(ctx.motions)),
    "longrun": ("motions", lambda ctx: suites.longrun_suite(ctx.motions, ctx.reference)),
    "quality": ("motions", lambda ctx: suites.quality_suite(ctx.motions, ctx.reference)),
    "affect": ("motions", lambda ctx: suites.affect_suite(ctx.motions, ctx.reference)),
    "speed": ("generator", _speed),
}


def run_suites(subject: Subject, suite: str, classifier: EmotionClassifier | None = None,
               progress: bool = False, requests: list[GenerationRequest] | None = None,
               ) -> tuple[dict[str, dict], dict]:
    """Run one suite or ``"all"`` on a subject.

    ``requests`` replace :func:`~emotive.eval.sources.standard_requests` for a generator
    (either way reduced to what the generator can honour,
    :func:`~emotive.eval.sources.requests_for`).

    Returns:
        ``(suite name -> result, facts for the report)``.

    Raises:
        EvaluationError: unknown suite, or one the subject cannot be judged by.
    """
    if suite != "all" and suite not in SUITES:
        raise EvaluationError(f"unknown suite {suite!r}: use one of {', '.join(SUITES)} or all")
    provided = subject.provides()
    names = [s for s, (need, _) in SUITES.items() if need in provided] if suite == "all" else [
        suite]
    need = SUITES[names[0]][0] if names else None
    if not names or need not in provided:
        raise EvaluationError(
            f"suite {suite!r} needs {NEEDS.get(need or '', 'a model')}, and {subject.name} "
            f"provides {', '.join(sorted(provided)) or 'nothing'}; suites it supports: "
            f"{', '.join(s for s, (n, _) in SUITES.items() if n in provided)}"
        )
    classifier = classifier or subject.classifier or load_default_classifier()
    ctx = Context(subject, classifier,
                  requests if requests is not None else standard_requests(classifier.labels))
    results = {}
    for name in track(names, description="evaluating", disable=not progress,
                      console=Console(stderr=True), transient=True):
        results[name] = SUITES[name][1](ctx)
    real = suites.real_test_metrics(classifier).get("window_accuracy", float("nan"))
    info = {
        "model": subject.name,
        "suites": ", ".join(names),
        "classifier": f"{', '.join(classifier.labels)}; real held-out window accuracy {real:.3f}",
    }
    if ctx._reference_error:
        info["real reference"] = f"unavailable ({ctx._reference_error})"
    return results, info
