"""``study.toml``: the design of one perceptual study, read and checked.

A study shows every participant a sequence of *items*; an item is one stimulus (a motion,
looping, at a fixed camera) and every question of the study about it. The file holds::

    title = "How do these walkers feel?"
    template = "gaits"          # the design it was made from (gaits, affect-grid, sources)
    seed = 0                    # orders and conditions are functions of (seed, join order)
    seconds = 10.0              # every stimulus loops over this many seconds
    render = "mannequin"        # mannequin | sticks | effectors (conditions may override)
    repeats = 1                 # times each stimulus is rated; pass 2 starts once all are rated
    completion_code = "EMO-..."
    consent = "..."
    instructions = "..."
    between = "source"          # name of the between-subject factor, "" for none

    [[conditions]]              # between-subject groups; participants are spread evenly
    name = "mocap"
    render = "sticks"           # optional
    stimuli = ["s01", "s02"]    # optional: default every stimulus

    [[questions]]
    id = "happy"
    kind = "likert"             # likert (min..max), choice (options), grid (size x size)
    prompt = "How happy does the character look?"
    min = 1
    max = 5
    anchors = ["not at all", "very"]

    [[stimuli]]
    id = "s01"
    file = "stimuli/s01.glb"
    source = "gait"
    intended = "happy"          # emotion text (emotive.data.emotion), "" when none
    recipe = {model = "gait", emotion = "happy", path = "circle", seed = 1}

    [[attention_checks]]        # instructed-response items (careless raters fail them)
    id = "check-1"
    stimulus = "s01"
    position = 3                # shown after this many items of the first pass
    instruction = "Attention check: answer 1 on every scale for this clip."
    expect = {happy = 1, sad = 1}

    [limits]
    submit_per_second = 5.0     # per participant
    submit_burst = 20
    joins_per_minute = 600.0    # per client address
    max_body_bytes = 16384

Answers are stored per question: a likert answer is an integer in ``min..max``, a choice
answer one of ``options``, a grid answer ``{"valence": column, "arousal": row}`` (cells
``1..size``, arousal counted from the bottom) stored as two values ``valence`` and ``arousal``
on the -1..1 scale of the FCRBM paper (Alemi et al. 2015, section V).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from emotive.data.emotion import DEFAULT_LABELS, Emotion, coerce_blend
from emotive.errors import EmotionError
from emotive.study.errors import StudyConfigError

#: The study file's name inside a study folder.
STUDY_FILE = "study.toml"
#: How a stimulus is drawn: the skinned mannequin, lines between joints, or only the
#: end effectors with their traces (Carreno-Medrano et al. 2018, section 7.1.1).
RENDERS = ("mannequin", "sticks", "effectors")
#: Kinds of question.
KINDS = ("likert", "choice", "grid")
#: Names of the two values a grid answer is stored as.
GRID_VALUES = ("valence", "arousal")
#: Allowed ids of stimuli, questions, conditions and checks.
ID_PATTERN = re.compile(r"^[A-Za-z0-9_-]{1,40}$")


@dataclass(frozen=True)
class Question:
    """One question asked about every item.

    Attributes:
        id: its name in responses and exports.
        kind: ``likert``, ``choice`` or ``grid``.
        prompt: the text shown.
        min: lowest likert value.
        max: highest likert value.
        anchors: texts shown at the two ends of a likert scale or the grid's axes.
        options: the choices of a ``choice`` question.
        size: cells per side of a ``grid``.
    """

    id: str
    kind: str
    prompt: str
    min: int = 1
    max: int = 5
    anchors: tuple[str, ...] = ()
    options: tuple[str, ...] = ()
    size: int = 9

    @property
    def stored(self) -> tuple[str, ...]:
        """The names its answer is stored under (two for a grid, else its id)."""
        return GRID_VALUES if self.kind == "grid" else (self.id,)


@dataclass(frozen=True)
class Stimulus:
    """One motion shown to participants.

    Attributes:
        id: its public name (does not reveal the intended emotion).
        file: the GLB the page plays, relative to the study folder.
        source: where it comes from (a model name, ``recorded``, ``reconstructed``, ...).
        intended: the intended emotion as text, or ``""``.
        recipe: how it was made (model, emotion, path, seed, input file), for the record.
    """

    id: str
    file: str
    source: str = ""
    intended: str = ""
    recipe: dict[str, Any] = field(default_factory=dict)

    def intended_emotion(self) -> Emotion | None:
        """The intended emotion over the default labels, or ``None`` when not given.

        A valence/arousal point (``"valence=0.5,arousal=-0.2"``) is blended over the labels
        by :func:`emotive.data.emotion.coerce_blend`.
        """
        return coerce_blend(self.intended, DEFAULT_LABELS) if self.intended else None


@dataclass(frozen=True)
class Condition:
    """A between-subject group: its render and the stimuli it shows.

    Attributes:
        name: the group's name (a level of :attr:`StudyConfig.between`).
        render: how its stimuli are drawn.
        stimuli: ids of the stimuli it shows, in the study's order.
    """

    name: str
    render: str
    stimuli: tuple[str, ...]


@dataclass(frozen=True)
class AttentionCheck:
    """An instructed-response item: a stimulus with an instruction and the answers expected.

    Attributes:
        id: its name in responses.
        stimulus: the stimulus shown.
        position: shown after this many items of the first pass.
        instruction: the text that tells the participant what to answer.
        expect: question id -> expected answer (grid: ``[valence cell, arousal cell]``).
    """

    id: str
    stimulus: str
    position: int
    instruction: str
    expect: dict[str, Any]


@dataclass(frozen=True)
class Limits:
    """Rate and size limits of the study server.

    Attributes:
        submit_per_second: sustained submissions per participant.
        submit_burst: submissions a participant may send at once.
        joins_per_minute: new participants per client address.
        max_body_bytes: largest request body.
    """

    submit_per_second: float = 5.0
    submit_burst: int = 20
    joins_per_minute: float = 600.0
    max_body_bytes: int = 16384


@dataclass(frozen=True)
class StudyConfig:
    """A checked ``study.toml``; see the module docstring for every key.

    Attributes:
        folder: the study folder (absolute).
    """

    folder: Path
    title: str
    template: str
    seed: int
    seconds: float
    render: str
    repeats: int
    completion_code: str
    consent: str
    instructions: str
    between: str
    conditions: tuple[Condition, ...]
    questions: tuple[Question, ...]
    stimuli: tuple[Stimulus, ...]
    checks: tuple[AttentionCheck, ...]
    limits: Limits

    def stimulus(self, stimulus_id: str) -> Stimulus:
        """The stimulus of that id (``KeyError`` when there is none)."""
        return {s.id: s for s in self.stimuli}[stimulus_id]

    def question(self, question_id: str) -> Question:
        """The question of that id (``KeyError`` when there is none)."""
        return {q.id: q for q in self.questions}[question_id]

    def condition(self, name: str) -> Condition:
        """The condition of that name (``KeyError`` when there is none)."""
        return {c.name: c for c in self.conditions}[name]

    def stimulus_path(self, stimulus_id: str) -> Path:
        """The GLB file of a stimulus."""
        return self.folder / self.stimulus(stimulus_id).file

    @property
    def design_fingerprint(self) -> str:
        """sha256 of everything a participant's plan and answers depend on.

        The server keeps the fingerprint of the study it first served and refuses a changed
        design, so that responses already stored keep their meaning.
        """
        design = {
            "seed": self.seed, "repeats": self.repeats,
            "conditions": [asdict(c) for c in self.conditions],
            "questions": [asdict(q) for q in self.questions],
            "stimuli": [s.id for s in self.stimuli],
            "checks": [asdict(c) for c in self.checks],
        }
        text = json.dumps(design, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _fail(path: Path, where: str, problem: str) -> StudyConfigError:
    return StudyConfigError(f"{path}: {where}: {problem}")


class _Reader:
    """Typed access to one table of the file, with errors naming the key."""

    def __init__(self, path: Path, table: dict[str, Any], where: str) -> None:
        self.path, self.table, self.where = path, table, where

    def fail(self, key: str, problem: str) -> StudyConfigError:
        return _fail(self.path, f"{self.where}{key}", problem)

    def get(self, key: str, kind: type | tuple[type, ...], default: Any = None) -> Any:
        if key not in self.table:
            if default is None:
                raise self.fail(key, "is missing")
            return default
        value = self.table[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if isinstance(value, bool) and bool not in kinds:
            raise self.fail(key, f"must be {' or '.join(k.__name__ for k in kinds)}, not {value!r}")
        if not isinstance(value, kinds):
            raise self.fail(key, f"must be {' or '.join(k.__name__ for k in kinds)}, "
                            f"not {type(value).__name__} {value!r}")
        return value

    def ident(self, key: str) -> str:
        value = self.get(key, str)
        if not ID_PATTERN.match(value):
            raise self.fail(key, f"{value!r} must be 1-40 letters, digits, '_' or '-'")
        return value

    def strings(self, key: str, default: tuple[str, ...] | None = None) -> tuple[str, ...]:
        value = self.get(key, list, default=list(default) if default is not None else None)
        if not all(isinstance(v, str) for v in value):
            raise self.fail(key, f"must be a list of strings, not {value!r}")
        return tuple(value)

    def unknown(self, allowed: set[str]) -> None:
        extra = sorted(set(self.table) - allowed)
        if extra:
            raise _fail(self.path, self.where.rstrip(".") or "the file",
                        f"unknown key(s) {extra}; allowed: {sorted(allowed)}")


def _question(path: Path, table: dict[str, Any], index: int) -> Question:
    r = _Reader(path, table, f"questions[{index}].")
    r.unknown({"id", "kind", "prompt", "min", "max", "anchors", "options", "size"})
    qid, kind, prompt = r.ident("id"), r.get("kind", str), r.get("prompt", str)
    if kind not in KINDS:
        raise r.fail("kind", f"{kind!r} is not one of {', '.join(KINDS)}")
    if kind == "likert":
        low, high = r.get("min", int, 1), r.get("max", int, 5)
        if not 0 <= low < high <= 100:
            raise r.fail("max", f"a likert scale needs 0 <= min < max <= 100, got {low}..{high}")
        anchors = r.strings("anchors", ())
        if len(anchors) not in (0, 2):
            raise r.fail("anchors", "give two texts, for the low and the high end")
        return Question(qid, kind, prompt, min=low, max=high, anchors=anchors)
    if kind == "choice":
        options = r.strings("options")
        if len(options) < 2 or len(set(options)) != len(options):
            raise r.fail("options", f"needs at least two distinct options, got {list(options)}")
        return Question(qid, kind, prompt, options=options)
    size = r.get("size", int, 9)
    if size < 3 or size > 21 or size % 2 == 0:
        raise r.fail("size", f"a grid needs an odd size from 3 to 21 (a centre cell), got {size}")
    anchors = r.strings("anchors", ())
    if len(anchors) not in (0, 4):
        raise r.fail("anchors", "give four texts: unpleasant, pleasant, low and high arousal")
    if qid in GRID_VALUES:
        raise r.fail("id", f"a grid question's answer is stored as {GRID_VALUES}; name it "
                     "otherwise (e.g. 'affect')")
    return Question(qid, kind, prompt, anchors=anchors, size=size)


def _stimulus(path: Path, table: dict[str, Any], index: int) -> Stimulus:
    r = _Reader(path, table, f"stimuli[{index}].")
    r.unknown({"id", "file", "source", "intended", "recipe"})
    sid, file = r.ident("id"), r.get("file", str)
    if Path(file).is_absolute() or ".." in Path(file).parts or not file.endswith(".glb"):
        raise r.fail("file", f"{file!r} must be a .glb path inside the study folder")
    intended = r.get("intended", str, "")
    if intended:  # a label, a blend, or a valence/arousal point
        try:
            coerce_blend(intended, DEFAULT_LABELS)
        except EmotionError as exc:
            raise r.fail("intended", str(exc)) from None
    return Stimulus(sid, file, r.get("source", str, ""), intended, dict(r.get("recipe", dict, {})))


def check_answer(question: Question, value: Any) -> str | None:
    """Why ``value`` is not a valid answer to ``question``, or ``None`` when it is.

    Likert: an integer in range (not a bool, not a float); choice: one of the options; grid:
    ``{"valence": int, "arousal": int}`` with cells in ``1..size``.
    """
    if question.kind == "likert":
        if isinstance(value, bool) or not isinstance(value, int):
            return f"{question.id!r} takes an integer from {question.min} to {question.max}"
        if not question.min <= value <= question.max:
            return f"{question.id!r} is {value}, outside {question.min}..{question.max}"
        return None
    if question.kind == "choice":
        if not isinstance(value, str) or value not in question.options:
            return f"{question.id!r} takes one of {list(question.options)}"
        return None
    if not isinstance(value, dict) or set(value) != set(GRID_VALUES):
        return f"{question.id!r} takes {{\"valence\": cell, \"arousal\": cell}}"
    for key in GRID_VALUES:
        cell = value[key]
        if isinstance(cell, bool) or not isinstance(cell, int) or not 1 <= cell <= question.size:
            return f"{question.id!r}.{key} takes an integer cell from 1 to {question.size}"
    return None


def stored_values(question: Question, value: Any) -> dict[str, float | str]:
    """A checked answer as the values stored: name -> number or text.

    A grid cell ``c`` of ``n`` is stored as ``2 (c - 1) / (n - 1) - 1`` on -1..1.
    """
    if question.kind == "grid":
        n = question.size - 1
        return {key: 2.0 * (value[key] - 1) / n - 1.0 for key in GRID_VALUES}
    if question.kind == "likert":
        return {question.id: float(value)}
    return {question.id: value}


def _check(path: Path, table: dict[str, Any], index: int, questions: dict[str, Question],
           stimuli: set[str]) -> AttentionCheck:
    r = _Reader(path, table, f"attention_checks[{index}].")
    r.unknown({"id", "stimulus", "position", "instruction", "expect"})
    check = AttentionCheck(r.ident("id"), r.get("stimulus", str), r.get("position", int),
                           r.get("instruction", str), dict(r.get("expect", dict)))
    if check.stimulus not in stimuli:
        raise r.fail("stimulus", f"{check.stimulus!r} is not a stimulus of the study")
    if check.position < 0:
        raise r.fail("position", f"must be 0 or more, got {check.position}")
    if not check.expect:
        raise r.fail("expect", "name at least one question and the answer it expects")
    for qid, value in check.expect.items():
        if qid not in questions:
            raise r.fail("expect", f"{qid!r} is not a question of the study")
        question = questions[qid]
        if question.kind == "grid" and isinstance(value, list) and len(value) == 2:
            value = dict(zip(GRID_VALUES, value, strict=True))
        problem = check_answer(question, value)
        if problem:
            raise r.fail("expect", problem)
    return check


def _conditions(path: Path, raw: list[Any], render: str, stimuli: tuple[str, ...]
                ) -> tuple[Condition, ...]:
    if not raw:
        return (Condition("all", render, stimuli),)
    out = []
    for i, table in enumerate(raw):
        if not isinstance(table, dict):
            raise _fail(path, f"conditions[{i}]", "must be a table")
        r = _Reader(path, table, f"conditions[{i}].")
        r.unknown({"name", "render", "stimuli"})
        cond_render = r.get("render", str, render)
        if cond_render not in RENDERS:
            raise r.fail("render", f"{cond_render!r} is not one of {', '.join(RENDERS)}")
        shown = r.strings("stimuli", stimuli)
        unknown = sorted(set(shown) - set(stimuli))
        if unknown:
            raise r.fail("stimuli", f"{unknown} are not stimuli of the study")
        if not shown or len(set(shown)) != len(shown):
            raise r.fail("stimuli", "must name at least one stimulus, each once")
        out.append(Condition(r.ident("name"), cond_render, shown))
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise _fail(path, "conditions", f"names must differ, got {names}")
    return tuple(out)


def _unique(path: Path, where: str, ids: list[str]) -> None:
    seen = {i for i in ids if ids.count(i) > 1}
    if seen:
        raise _fail(path, where, f"ids must be unique; repeated: {sorted(seen)}")


def _limits(path: Path, table: Any) -> Limits:
    if not isinstance(table, dict):
        raise _fail(path, "limits", "must be a table")
    r = _Reader(path, table, "limits.")
    r.unknown({"submit_per_second", "submit_burst", "joins_per_minute", "max_body_bytes"})
    base = Limits()
    limits = Limits(float(r.get("submit_per_second", (int, float), base.submit_per_second)),
                    r.get("submit_burst", int, base.submit_burst),
                    float(r.get("joins_per_minute", (int, float), base.joins_per_minute)),
                    r.get("max_body_bytes", int, base.max_body_bytes))
    for name, value in asdict(limits).items():
        if not (math.isfinite(value) and value > 0):
            raise r.fail(name, f"must be a positive number, got {value}")
    if limits.max_body_bytes < 1024:
        raise r.fail("max_body_bytes", "must be at least 1024 (one item's answers)")
    return limits


_TOP_KEYS = {"title", "template", "seed", "seconds", "render", "repeats", "completion_code",
             "consent", "instructions", "between", "conditions", "questions", "stimuli",
             "attention_checks", "limits"}


def parse_study(folder: Path, data: dict[str, Any], path: Path) -> StudyConfig:
    """A :class:`StudyConfig` from the parsed TOML of ``path`` (see :func:`load_study`)."""
    r = _Reader(path, data, "")
    r.unknown(_TOP_KEYS)
    render = r.get("render", str, "mannequin")
    if render not in RENDERS:
        raise r.fail("render", f"{render!r} is not one of {', '.join(RENDERS)}")
    seconds = float(r.get("seconds", (int, float), 10.0))
    if not 1.0 <= seconds <= 120.0:
        raise r.fail("seconds", f"must be from 1 to 120, got {seconds}")
    repeats = r.get("repeats", int, 1)
    if not 1 <= repeats <= 5:
        raise r.fail("repeats", f"must be from 1 to 5, got {repeats}")
    seed = r.get("seed", int, 0)
    code = r.get("completion_code", str)
    if not 4 <= len(code) <= 64:
        raise r.fail("completion_code", "must be 4 to 64 characters")
    raw_q, raw_s = r.get("questions", list), r.get("stimuli", list)
    if not raw_q or not raw_s:
        raise _fail(path, "questions/stimuli", "a study needs at least one question and one "
                    "stimulus")
    for name, raw in (("questions", raw_q), ("stimuli", raw_s)):
        if not all(isinstance(t, dict) for t in raw):
            raise _fail(path, name, "must be an array of tables ([[" + name + "]])")
    questions = tuple(_question(path, t, i) for i, t in enumerate(raw_q))
    stimuli = tuple(_stimulus(path, t, i) for i, t in enumerate(raw_s))
    _unique(path, "questions", [q.id for q in questions])
    _unique(path, "stimuli", [s.id for s in stimuli])
    stored = [name for q in questions for name in q.stored]
    _unique(path, "questions (stored values)", stored)
    by_id = {q.id: q for q in questions}
    raw_c = r.get("attention_checks", list, [])
    checks = tuple(_check(path, t, i, by_id, {s.id for s in stimuli})
                   for i, t in enumerate(raw_c))
    _unique(path, "attention_checks", [c.id for c in checks])
    clash = sorted({c.id for c in checks} & {s.id for s in stimuli})
    if clash:
        raise _fail(path, "attention_checks", f"ids {clash} are also stimulus ids")
    conditions = _conditions(path, r.get("conditions", list, []), render,
                             tuple(s.id for s in stimuli))
    return StudyConfig(
        folder=folder, title=r.get("title", str), template=r.get("template", str, "custom"),
        seed=seed, seconds=seconds, render=render, repeats=repeats, completion_code=code,
        consent=r.get("consent", str), instructions=r.get("instructions", str, ""),
        between=r.get("between", str, ""), conditions=conditions, questions=questions,
        stimuli=stimuli, checks=checks, limits=_limits(path, data.get("limits", {})),
    )


def load_study(folder: str | Path, check_files: bool = True) -> StudyConfig:
    """Read and check ``FOLDER/study.toml``.

    Args:
        folder: the study folder.
        check_files: also check that every stimulus file is there.

    Raises:
        StudyConfigError: no such folder or file, bad TOML, a missing or bad key or value, or
            a missing stimulus file; the message names the key and the fix.
    """
    folder = Path(folder).expanduser().resolve()
    path = folder / STUDY_FILE
    if not path.is_file():
        raise StudyConfigError(f"{folder} is not a study folder (no {STUDY_FILE}); make one "
                               "with `emotive study init DIR --template gaits`")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise StudyConfigError(f"{path}: not valid TOML ({exc})") from None
    study = parse_study(folder, data, path)
    if check_files:
        missing = [s.file for s in study.stimuli if not (folder / s.file).is_file()]
        if missing:
            raise StudyConfigError(f"{path}: stimulus files missing: {missing[:5]}; make them "
                                   "again with `emotive study init` or fix the paths")
    return study
