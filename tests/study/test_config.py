"""``study.toml``: every key checked with a message naming it and the fix; answers checked
and stored on the study's scales."""

from __future__ import annotations

from pathlib import Path

import pytest

from emotive.study.config import check_answer, load_study, parse_study, stored_values
from emotive.study.errors import StudyConfigError

BASE = {
    "title": "t", "consent": "c", "completion_code": "CODE-1",
    "questions": [{"id": "happy", "kind": "likert", "prompt": "?", "min": 1, "max": 5},
                  {"id": "emotion", "kind": "choice", "prompt": "?",
                   "options": ["happy", "sad"]},
                  {"id": "affect", "kind": "grid", "prompt": "?", "size": 9}],
    "stimuli": [{"id": "s1", "file": "stimuli/s1.glb", "intended": "happy"}],
}


def _parse(**changes):
    return parse_study(Path("/s"), {**BASE, **changes}, Path("/s/study.toml"))


@pytest.mark.parametrize(("changes", "words"), [
    ({"colour": "red"}, "unknown key(s) ['colour']"),
    ({"render": "wire"}, "render: 'wire' is not one of mannequin, sticks, effectors"),
    ({"seconds": 0.5}, "seconds: must be from 1 to 120"),
    ({"repeats": 9}, "repeats: must be from 1 to 5"),
    ({"seed": "one"}, "seed: must be int"),
    ({"stimuli": [{"id": "s1", "file": "../x.glb"}]}, "must be a .glb path inside"),
    ({"stimuli": [{"id": "s 1", "file": "stimuli/a.glb"}]}, "letters, digits"),
    ({"stimuli": [{"id": "s1", "file": "a.glb", "intended": "gleeful"}]}, "gleeful"),
    ({"stimuli": [{"id": "s1", "file": "a.glb"}, {"id": "s1", "file": "b.glb"}]},
     "repeated: ['s1']"),
    ({"questions": [{"id": "q", "kind": "slider", "prompt": "?"}]}, "'slider' is not one of"),
    ({"questions": [{"id": "q", "kind": "likert", "prompt": "?", "min": 5, "max": 5}]},
     "min < max"),
    ({"questions": [{"id": "q", "kind": "grid", "prompt": "?", "size": 8}]}, "odd size"),
    ({"questions": [{"id": "valence", "kind": "grid", "prompt": "?"}]}, "name it otherwise"),
    ({"conditions": [{"name": "a", "stimuli": ["s9"]}]}, "['s9'] are not stimuli"),
    ({"attention_checks": [{"id": "k", "stimulus": "s1", "position": 1, "instruction": "x",
                            "expect": {"happy": 7}}]}, "outside 1..5"),
    ({"attention_checks": [{"id": "k", "stimulus": "s1", "position": 1, "instruction": "x",
                            "expect": {"mood": 1}}]}, "'mood' is not a question"),
    ({"limits": {"submit_per_second": 0}}, "must be a positive number"),
])
def test_bad_keys_name_the_key_and_the_fix(changes, words):
    with pytest.raises(StudyConfigError, match=None) as err:
        _parse(**changes)
    assert words in str(err.value)
    assert str(err.value).startswith("/s/study.toml")


def test_a_folder_without_a_study_says_how_to_make_one(tmp_path: Path):
    with pytest.raises(StudyConfigError, match="emotive study init"):
        load_study(tmp_path)
    (tmp_path / "study.toml").write_text("title = [")
    with pytest.raises(StudyConfigError, match="not valid TOML"):
        load_study(tmp_path)


def test_answers_are_checked_and_stored_on_the_study_scales():
    study = _parse()
    likert, choice, grid = study.questions
    assert check_answer(likert, 3) is None
    for bad in (0, 6, 3.0, True, "3", None):
        assert check_answer(likert, bad)
    assert check_answer(choice, "sad") is None and check_answer(choice, "angry")
    assert check_answer(grid, {"valence": 1, "arousal": 9}) is None
    for bad in ({"valence": 0, "arousal": 5}, {"valence": 5}, [5, 5], {"valence": 5.0,
                                                                       "arousal": 5}):
        assert check_answer(grid, bad)
    assert stored_values(grid, {"valence": 1, "arousal": 9}) == {"valence": -1.0,
                                                                 "arousal": 1.0}
    assert stored_values(grid, {"valence": 5, "arousal": 3}) == {"valence": 0.0,
                                                                 "arousal": -0.5}
    assert stored_values(likert, 4) == {"happy": 4.0}
    assert stored_values(choice, "sad") == {"emotion": "sad"}
