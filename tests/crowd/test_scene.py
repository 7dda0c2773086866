"""Scene files: the structure, the geometry checks (one typed line naming the group and the
fix), serialisation."""

from __future__ import annotations

import json

import pytest
from tests.crowd.conftest import CORRIDOR, write_scene

from emotive.crowd.errors import SceneError
from emotive.crowd.scene import Scene, load_scene

AREA = "[area]\npolygon = [[0, 0], [10, 0], [10, 4], [0, 4]]\n"
OBSTACLE = "[[area.obstacles]]\npolygon = [[4, 0], [6, 0], [6, 4], [4, 4]]\n"


def group(spawn="[[0.5, 0.5], [2, 0.5], [2, 3.5], [0.5, 3.5]]",
          goal="[[9, 0.5], [9.8, 0.5], [9.8, 3.5], [9, 3.5]]", count=3, extra=""):
    return (f'[[groups]]\nname = "walkers"\nspawn = {spawn}\ncount = {count}\n'
            f'goal = {goal}\nemotion = "happy"\n{extra}')


BAD = [
    ("self-intersecting area", "[area]\npolygon = [[0, 0], [10, 4], [10, 0], [0, 4]]\n"
     + group(), ["[area] polygon", "crosses itself", "in order"]),
    ("open spawn", AREA + group(spawn="[[1, 1], [2, 2]]"),
     ["group 'walkers' spawn", "open", "at least 3 points"]),
    ("collinear goal", AREA + group(goal="[[8, 1], [9, 1], [9.5, 1]]"),
     ["group 'walkers' goal", "open"]),
    ("self-intersecting spawn", AREA + group(spawn="[[0.5, 0.5], [2, 3.5], [2, 0.5], "
                                              "[0.5, 3.5]]"),
     ["group 'walkers' spawn", "crosses itself"]),
    ("spawn outside", AREA + group(spawn="[[-3, 0.5], [-1, 0.5], [-1, 3], [-3, 3]]"),
     ["group 'walkers' spawn", "outside the area or inside an obstacle", "move it"]),
    ("spawn in obstacle", AREA + "[[area.obstacles]]\npolygon = [[0, 0], [3, 0], [3, 4], "
     "[0, 4]]\n" + group(), ["group 'walkers' spawn", "inside an obstacle"]),
    ("goal outside", AREA + group(goal="[[11, 1], [12, 1], [12, 2], [11, 2]]"),
     ["group 'walkers' goal", "outside the area", "move the goal"]),
    ("goal unreachable", AREA + OBSTACLE + group(),
     ["group 'walkers' goal", "no path reaches it", "open a way"]),
    ("waypoint in obstacle", AREA + "[[area.obstacles]]\npolygon = [[4, 1], [6, 1], [6, 3], "
     "[4, 3]]\n" + group(goal="{ waypoints = [[5, 2]] }"),
     ["group 'walkers' goal waypoint 1", "inside an obstacle"]),
    ("too many agents", AREA + group(count=500),
     ["group 'walkers' spawn", "holds", "asks for 500", "enlarge the spawn"]),
    ("no emotion", AREA + '[[groups]]\nname = "walkers"\nspawn = [[1, 1], [2, 1], [2, 2]]\n'
     "count = 1\ngoal = \"wander\"\n", ["group 'walkers'", "no emotion"]),
    ("bad pace", AREA + group(extra="pace = [1.2, 0.7]\n"), ["group 'walkers' pace", "lo <= hi"]),
    ("unknown key", AREA + group(extra="speed = 2\n"), ["group 'walkers'", "unknown key 'speed'"]),
    ("no groups", AREA, ["no [[groups]]"]),
]


@pytest.mark.parametrize(("case", "text", "words"), BAD, ids=[b[0] for b in BAD])
def test_each_bad_scene_is_one_typed_line_naming_the_group_and_the_fix(tmp_path, case, text,
                                                                       words):
    path = write_scene(tmp_path, text)
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    message = str(exc.value)
    assert "\n" not in message
    assert str(path) in message
    for word in words:
        assert word in message, (case, message)


def test_a_scene_is_a_plain_value_that_round_trips(corridor):
    scene = load_scene(corridor)
    again = Scene.from_dict(json.loads(json.dumps(scene.to_dict())))
    assert again == scene
    assert hash(again) == hash(scene)
    assert [g.name for g in scene.groups] == ["east", "west"]
    assert scene.groups[0].emotion.choices == ("happy", "angry", "neutral")
    assert scene.groups[1].goal.kind == "exit"


def test_the_example_scenes_are_valid():
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "examples" / "scenes"
    names = sorted(p.name for p in folder.glob("*.toml"))
    assert names == ["corridor.toml", "plaza.toml", "room-exit.toml"]
    counts = {n: sum(g.count for g in load_scene(folder / n).groups) for n in names}
    assert counts == {"corridor.toml": 200, "plaza.toml": 300, "room-exit.toml": 100}


def test_a_bad_scene_on_the_command_line_writes_nothing(tmp_path, monkeypatch, capsys):
    from tests.cli_helpers import run_main

    path = write_scene(tmp_path, CORRIDOR.format(count=900))
    out = tmp_path / "out"
    code, _, err = run_main(monkeypatch, capsys, "crowd", path, "--seconds", "1", "--out", out)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "group 'east' spawn" in lines[0] and "holds" in lines[0]
    assert not out.exists()
