"""Control messages into commands: paths, emotions, fields, and no file ever opened."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.emotion import DEFAULT_LABELS
from emotive.serve.errors import MessageError
from emotive.serve.messages import AddAgent, parse_emotion, parse_path, to_command

LABELS = DEFAULT_LABELS


def test_paths_of_every_form():
    drawn = parse_path([[0, 0], [1, 1], [2, 0]])
    np.testing.assert_allclose(drawn.points[0], [0, 0])
    np.testing.assert_allclose(drawn.points[-1], [2, 0], atol=1e-9)
    assert not drawn.closed
    loop = parse_path({"points": [[0, 0], [2, 0], [2, 2], [0, 2]], "closed": True})
    assert loop.closed
    assert parse_path("figure8").closed and parse_path(None).name == "circle"
    placed = parse_path({"shape": "circle", "center": [5, -3], "radius": 1})
    np.testing.assert_allclose(0.5 * (placed.points.min(0) + placed.points.max(0)), [5, -3],
                               atol=1e-6)
    assert np.linalg.norm(placed.points - [5, -3], axis=1).max() == pytest.approx(1, abs=1e-3)
    assert parse_path({"shape": "line", "length": 3}).length == pytest.approx(3)


@pytest.mark.parametrize(("path", "match"), [
    ([[0, 0]], "at least two"),
    ([], "at least two"),
    ([[0, 0], [0, 0]], "two distinct"),
    ([[0, 0], [1]], r"\[x, z\] pairs"),
    ([[0, 0], ["a", 1]], "finite number"),
    ([[0, 0], [True, 1]], "finite number"),
    ([[0, 0], [10**400, 1]], "beyond float range"),
    ([[0, 0], [1e9, 0]], "beyond the scene"),
    ({"shape": "circle", "center": [300, 0]}, "beyond the scene"),
    ("spiral", "unknown"),
    ({"shape": "circle", "radius": -1}, "positive"),
    ({"shape": "circle", "size": 2}, "unknown size"),
    ({"shape": "zigzag", "count": 2.5}, "whole number"),
    ({"points": [[0, 0], [1, 0]], "closed": "yes"}, "closed"),
    (42, '"path" must be'),
    ([[0, -200], [0, 200], [200, 200], [200, -200]], "limit is 500 m"),
    ([[k * 0.01, 0] for k in range(10_001)], "limit of 10000"),
    ({"shape": "line", "length": 1e5}, "limit is 500 m"),
    ({"shape": "zigzag", "leg": 100, "count": 100}, "limit is 500 m"),
])
def test_bad_paths_are_named(path, match):
    with pytest.raises(MessageError, match=match):
        parse_path(path)


def test_emotions_of_every_form():
    happy = LABELS.index("happy")
    blend = parse_emotion({"type": "x", "emotion": "happy=0.7,neutral=0.3"}, LABELS)
    assert blend.weights[0, happy] == pytest.approx(0.7)
    mapping = parse_emotion({"type": "x", "emotion": {"sad": 1}}, LABELS)
    assert mapping.weights[0, LABELS.index("sad")] == 1
    point = parse_emotion({"type": "x", "emotion": {"valence": 0.5, "arousal": -0.2}}, LABELS)
    np.testing.assert_allclose(point.points[0], [0.5, -0.2])
    schedule = parse_emotion({"type": "x", "schedule": [{"t": 0, "emotion": "sad"},
                                                        {"t": 5, "emotion": "happy"}]}, LABELS)
    assert schedule.duration == 5
    assert parse_emotion({"type": "x"}, LABELS, "neutral").weights[0, LABELS.index("neutral")]


@pytest.mark.parametrize(("message", "match"), [
    ({"emotion": "furious"}, "furious"),
    ({"emotion": {"happy": -1}}, "outside 0..1"),
    ({"emotion": {"happy": 0}}, "zero"),
    ({"emotion": 3}, '"emotion" is text'),
    ({"emotion": "sad", "schedule": []}, "not both"),
    ({"schedule": "sad"}, "list of keyframes"),
    ({"schedule": [{"t": 0.01 * k, "emotion": "sad"} for k in range(257)]},
     "257 keyframes, more than the limit of 256"),
    ({"schedule": [{"t": -1, "emotion": "sad"}]}, "t"),
    ({"emotion": "/etc/passwd"}, "not an emotion"),
    ({"emotion": "x.json"}, "not an emotion"),
    ({"emotion": '[{"t": 0, "emotion": "sad"}]'}, "not an emotion"),
    ({}, "needs"),
])
def test_bad_emotions_are_named(message, match):
    with pytest.raises(MessageError, match=match):
        parse_emotion({"type": "set_emotion", **message}, LABELS)


def test_commands_check_their_fields():
    add = to_command({"type": "add_agent", "pace": 1.2, "start": 2.0, "ref": 1}, LABELS)
    assert isinstance(add.value, AddAgent) and add.value.pace == 1.2
    assert to_command({"type": "set_pace", "id": 3, "pace": 0.5}, LABELS).agent == 3
    target = to_command({"type": "set_target", "id": 0, "target": [1, 2]}, LABELS)
    np.testing.assert_array_equal(target.value, [1, 2])
    assert to_command({"type": "stop_recording"}, LABELS).value is None
    for message, match in [
        ({"type": "fly"}, "unknown message type"),
        ({"type": "add_agent", "colour": "red"}, "no field colour"),
        ({"type": "set_emotion", "emotion": "sad"}, '"id"'),
        ({"type": "remove_agent", "id": True}, '"id"'),
        ({"type": "remove_agent", "id": "3"}, '"id"'),
        ({"type": "set_pace", "id": 1, "pace": 3}, "between"),
        ({"type": "set_target", "id": 1, "target": [1]}, r"\[x, z\]"),
        ({"type": "set_target", "id": 1, "target": [1, 1e4]}, "beyond the scene"),
        ({"type": "set_path", "id": 1}, "needs"),
        ({"type": "stop_recording", "id": "a"}, "recording id"),
    ]:
        with pytest.raises(MessageError, match=match):
            to_command(message, LABELS)
