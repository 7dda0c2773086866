"""The emotion model: parsing, errors, valence/arousal table and conversions, schedules."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from emotive.data import emotion as em
from emotive.data.emotion import (
    ALL_LABELS,
    DEFAULT_LABELS,
    VALENCE_AROUSAL,
    Emotion,
    EmotionSchedule,
    coerce_blend,
    coerce_emotion,
    valence_arousal,
)
from emotive.data.registry import REGISTRY
from emotive.errors import EmotionError


class TestLabels:
    def test_defaults_are_the_papers_four(self):
        assert DEFAULT_LABELS == ("happy", "sad", "angry", "neutral")

    def test_every_style_of_both_datasets_is_a_label(self):
        for info in REGISTRY.values():
            for style in info.styles:
                assert em.style_to_label(style) in ALL_LABELS
        assert em.style_to_label("normal") == "neutral"
        assert len(set(ALL_LABELS)) == len(ALL_LABELS) == 19

    def test_unknown_style(self):
        with pytest.raises(EmotionError, match="style 'sleepy'"):
            em.style_to_label("sleepy")


class TestParse:
    def test_blend(self):
        e = Emotion.parse("happy=0.7,neutral=0.3")
        assert e.labels == DEFAULT_LABELS
        np.testing.assert_allclose(e.weights, [0.7, 0, 0, 0.3])
        assert e["happy"] == pytest.approx(0.7) and e.dominant == "happy"

    def test_normalizes_and_accepts_spellings(self):
        e = Emotion.parse(" Happy : 0.4 , NORMAL=0.4 ")
        np.testing.assert_allclose(e.weights, [0.5, 0, 0, 0.5])

    def test_single_name(self):
        np.testing.assert_allclose(Emotion.parse("sad").weights, [0, 1, 0, 0])

    def test_extra_labels(self):
        labels = (*DEFAULT_LABELS, "proud", "not-confident")
        e = Emotion.parse("proud=0.25,not_confident=0.75", labels)
        assert e.to_dict() == {"proud": 0.25, "not-confident": 0.75}

    def test_round_trip_through_text(self):
        e = Emotion.parse("happy=0.25,angry=0.75")
        np.testing.assert_allclose(Emotion.parse(str(e)).weights, e.weights)

    @pytest.mark.parametrize(
        ("text", "message"),
        [
            ("hapy=1", r"unknown emotion 'hapy'.*did you mean 'happy'"),
            ("proud=1", r"'proud' .* not one of this model's labels"),
            ("happy=-0.2,sad=1", r"weight of 'happy' .* -0.2, outside 0\.\.1"),
            ("happy=2", r"weight of 'happy' in 'happy=2' is 2, outside 0\.\.1"),
            ("happy=1.0001,sad=1", r"1\.0001, outside 0\.\.1"),
            ("happy=nan", r"weight of 'happy' .* nan: use a finite number"),
            ("happy=inf", r"finite"),
            ("happy=0,sad=0", r"all weights are zero"),
            ("happy=abc", r"weight 'abc' of 'happy' .* not a number"),
            ("happy=1,happy=2", r"'happy' appears twice"),
            ("", r"empty emotion"),
            ("happy=1,,sad=1", r"extra comma"),
            ("=1", r"has no name"),
            ("happy=0.7,sad", r"entry 'sad' of the blend .* has no weight.*'sad=0.3'"),
            ("happy,sad", r"entry 'happy' of the blend .* has no weight"),
        ],
    )
    def test_errors(self, text, message):
        with pytest.raises(EmotionError, match=message):
            Emotion.parse(text)

    def test_error_names_the_input(self):
        with pytest.raises(EmotionError, match=r"'hapy=1,sad=2'"):
            Emotion.parse("hapy=1,sad=2")

    @pytest.mark.parametrize(
        "weights", [[1, 0, 0], [np.nan, 1, 0, 0], [-1, 2, 0, 0], [0, 0, 0, 0], [np.inf, 0, 0, 0]]
    )
    def test_bad_vectors(self, weights):
        with pytest.raises(EmotionError):
            Emotion(np.array(weights, dtype=float))

    def test_bad_labels(self):
        with pytest.raises(EmotionError, match="repeat"):
            Emotion(np.ones(2), ("happy", "happy"))
        with pytest.raises(EmotionError, match="unknown emotion 'glad'"):
            Emotion(np.ones(2), ("happy", "glad"))

    def test_weights_are_read_only(self):
        with pytest.raises(ValueError):
            Emotion.parse("happy").weights[0] = 2.0

    @given(st.lists(st.floats(0, 10), min_size=4, max_size=4).filter(lambda w: sum(w) > 1e-6))
    def test_any_valid_vector_normalizes(self, w):
        e = Emotion(np.array(w))
        assert e.weights.sum() == pytest.approx(1.0)
        assert np.all(e.weights >= 0)


class TestValenceArousal:
    def test_table_covers_every_label_and_style(self):
        assert set(VALENCE_AROUSAL) == set(ALL_LABELS)
        for info in REGISTRY.values():
            for style in info.styles:
                assert em.style_to_label(style) in VALENCE_AROUSAL

    def test_entries_are_in_range_and_sourced(self):
        for name, point in VALENCE_AROUSAL.items():
            assert -1 <= point.valence <= 1 and -1 <= point.arousal <= 1, name
            assert point.source in ("russell1980", "definition", "estimate"), name
        sources = {n: p.source for n, p in VALENCE_AROUSAL.items()}
        assert {n for n, s in sources.items() if s == "russell1980"} == {
            "happy", "sad", "angry", "tired"
        }
        assert sources["neutral"] == "definition"

    def test_russell_entries_follow_their_angles(self):
        for point in VALENCE_AROUSAL.values():
            if point.source == "russell1980":
                theta = math.radians(point.angle_deg)
                assert point.valence == pytest.approx(math.cos(theta), abs=1e-4)
                assert point.arousal == pytest.approx(math.sin(theta), abs=1e-4)

    def test_quadrants_of_the_four_emotions(self):
        va = {n: (VALENCE_AROUSAL[n].valence, VALENCE_AROUSAL[n].arousal) for n in DEFAULT_LABELS}
        assert va["happy"][0] > 0.5
        assert va["angry"][1] > 0.5 and va["angry"][0] < 0
        assert va["sad"][0] < 0 and va["sad"][1] < 0
        assert va["neutral"] == (0.0, 0.0)

    def test_module_docstring_names_sources_and_estimates(self):
        from emotive.data import circumplex

        doc = circumplex.__doc__
        assert "Russell" in doc and "1980" in doc and "own estimates" in doc

    def test_one_hot_gives_label_point(self):
        for name in ALL_LABELS:
            va = Emotion.one_hot(name, ALL_LABELS).valence_arousal()
            p = VALENCE_AROUSAL[name]
            np.testing.assert_allclose(va, [p.valence, p.arousal])

    def test_blend_is_weighted_mean(self):
        va = Emotion.parse("happy=0.5,sad=0.5").valence_arousal()
        h, s = VALENCE_AROUSAL["happy"], VALENCE_AROUSAL["sad"]
        np.testing.assert_allclose(va, [(h.valence + s.valence) / 2, (h.arousal + s.arousal) / 2])

    @pytest.mark.parametrize("labels", [DEFAULT_LABELS, ALL_LABELS])
    def test_back_from_a_label_point_favours_that_label(self, labels):
        points = em.label_points(labels)
        for c, name in enumerate(labels):
            e = Emotion.from_valence_arousal(*points[c], labels=labels)
            nearest = np.flatnonzero(np.all(points == points[c], axis=1))
            assert e.weights[nearest].sum() >= e.weights.max() - 1e-12
            assert np.argmax(e.weights) in nearest, name

    def test_batched_conversion_shapes(self):
        va = np.random.default_rng(0).uniform(-1, 1, (5, 7, 2))
        w = em.weights_from_valence_arousal(va)
        assert w.shape == (5, 7, 4)
        np.testing.assert_allclose(w.sum(-1), 1.0)
        assert em.valence_arousal(w).shape == (5, 7, 2)

    def test_bad_valence_arousal(self):
        with pytest.raises(EmotionError):
            em.weights_from_valence_arousal(np.array([np.nan, 0.0]))
        with pytest.raises(EmotionError):
            em.weights_from_valence_arousal(np.zeros(3))


KEYS = ({"t": 0, "emotion": {"angry": 1}}, {"t": 10, "emotion": {"happy": 1}})


class TestSchedule:

    def test_linear_interpolation_and_hold(self):
        s = EmotionSchedule.from_keyframes(list(KEYS))
        out = s.at(np.array([-1.0, 0.0, 2.5, 5.0, 10.0, 12.0]))
        happy, angry = DEFAULT_LABELS.index("happy"), DEFAULT_LABELS.index("angry")
        np.testing.assert_allclose(out[:, happy], [0, 0, 0.25, 0.5, 1, 1])
        np.testing.assert_allclose(out[:, angry], [1, 1, 0.75, 0.5, 0, 0])
        np.testing.assert_allclose(out.sum(1), 1.0)

    def test_sample_at_any_fps(self):
        s = EmotionSchedule.from_keyframes(list(KEYS))
        a = s.sample(30)
        assert a.shape == (301, 4)
        np.testing.assert_allclose(a.sum(1), 1.0)
        b = s.sample(12.5, num_frames=40)
        assert b.shape == (40, 4)
        np.testing.assert_allclose(b[25], s.at(2.0))
        assert s.sample(10, duration=20).shape == (201, 4)

    def test_renormalized_per_frame(self):
        keys = [{"t": 0, "emotion": "happy=0.2,sad=0.2"}, {"t": 1, "emotion": "angry=0.5"}]
        a = EmotionSchedule.from_keyframes(keys).sample(100)
        np.testing.assert_allclose(a.sum(1), 1.0, atol=1e-12)

    def test_instant_switch(self):
        keys = [
            {"t": 0, "emotion": "sad"}, {"t": 2, "emotion": "sad"}, {"t": 2, "emotion": "happy"}
        ]
        s = EmotionSchedule.from_keyframes(keys)
        assert s.at(1.999)[1] == pytest.approx(1.0)
        assert s.at(2.0)[0] == pytest.approx(1.0)

    def test_valence_arousal_keyframes(self):
        keys = [{"t": 0, "valence": 0.99, "arousal": 0.14}, {"t": 1, "emotion": "sad"}]
        s = EmotionSchedule.from_keyframes(keys)
        assert Emotion(s.at(0.0)).dominant == "happy"

    def test_constant(self):
        s = EmotionSchedule.constant(Emotion.parse("happy=0.7,neutral=0.3"))
        a = s.sample(30, num_frames=5)
        np.testing.assert_allclose(a, np.tile([0.7, 0, 0, 0.3], (5, 1)))

    def test_from_json_text_and_file(self, tmp_path):
        text = json.dumps(list(KEYS))
        path = tmp_path / "schedule.json"
        path.write_text(text)
        a = EmotionSchedule.from_json(text).sample(5)
        b = EmotionSchedule.from_json(path).sample(5)
        c = EmotionSchedule.parse(str(path)).sample(5)
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
        assert EmotionSchedule.from_keyframes(
            EmotionSchedule.from_json(text).to_keyframes()
        ).sample(5) == pytest.approx(a)

    def test_parse_constant(self):
        s = EmotionSchedule.parse("happy=0.7,neutral=0.3")
        assert s.duration == 0.0 and s.sample(30, num_frames=2).shape == (2, 4)

    def test_extra_labels_in_schedule(self):
        labels = ("happy", "tired")
        keys = [{"t": 0, "emotion": "tired"}, {"t": 4, "emotion": "happy"}]
        a = EmotionSchedule.from_keyframes(keys, labels).sample(1)
        np.testing.assert_allclose(a[:, 0], [0, 0.25, 0.5, 0.75, 1.0])

    @pytest.mark.parametrize(
        ("keys", "message"),
        [
            ([], "at least one keyframe"),
            ({"t": 0}, "list of keyframes"),
            ([{"emotion": "happy"}], r'keyframe 0 .* needs "t"'),
            ([{"t": -1, "emotion": "happy"}], r"keyframe 0 .*>= 0"),
            ([{"t": "soon", "emotion": "happy"}], "number of seconds"),
            ([{"t": 0, "emotion": "hapy"}], r"keyframe 0 .*unknown emotion 'hapy'"),
            ([{"t": 0}], r'give "emotion", or "valence" and "arousal"'),
            ([{"t": 0, "emotion": "happy", "speed": 2}], r"unknown keys \['speed'\]"),
            ([{"t": 5, "emotion": "happy"}, {"t": 1, "emotion": "sad"}], "sort the keyframes"),
            ([{"t": 0, "emotion": 3}], "mapping or text"),
            ([{"t": 0, "valence": "x", "arousal": 0}], "is not a number"),
        ],
    )
    def test_errors(self, keys, message):
        with pytest.raises(EmotionError, match=message):
            EmotionSchedule.from_keyframes(keys)

    def test_json_errors(self, tmp_path):
        with pytest.raises(EmotionError, match="not valid JSON"):
            EmotionSchedule.from_json("[{]")
        with pytest.raises(EmotionError, match=r"missing\.json does not exist"):
            EmotionSchedule.from_json(tmp_path / "missing.json")
        with pytest.raises(EmotionError, match=r"'not json' is not valid JSON \(line 1, column 1"):
            EmotionSchedule.from_json("not json")
        broken = tmp_path / "broken.json"
        broken.write_text('[{"t": 0,\n "emotion": }]')
        with pytest.raises(EmotionError, match=r"broken.json is not valid JSON \(line 2, column"):
            EmotionSchedule.from_json(broken)

    @given(
        st.lists(
            st.tuples(
                st.floats(0, 100),
                st.lists(st.floats(0, 1), min_size=4, max_size=4).filter(lambda w: sum(w) > 1e-3),
            ),
            min_size=1,
            max_size=6,
        ),
        st.floats(1, 120),
    )
    def test_samples_always_normalized(self, frames, fps):
        frames = sorted(frames, key=lambda f: f[0])
        s = EmotionSchedule(np.array([t for t, _ in frames]), np.array([w for _, w in frames]))
        a = s.sample(fps, num_frames=50)
        assert a.shape == (50, 4)
        np.testing.assert_allclose(a.sum(1), 1.0)
        assert np.all(a >= 0)


LABELS = DEFAULT_LABELS
finite_va = st.floats(-1, 1, allow_nan=False)


class TestCoerceEmotion:
    def test_every_form_of_a_label_gives_the_same_schedule(self, tmp_path):
        path = tmp_path / "k.json"
        path.write_text(json.dumps([{"t": 0, "emotion": "sad"}]))
        forms = ["sad", "SAD", {"sad": 1}, Emotion.one_hot("sad"), np.array([0, 1.0, 0, 0]),
                 EmotionSchedule.constant(Emotion.one_hot("sad")), [{"t": 0, "emotion": "sad"}],
                 path, str(path)]
        for form in forms:
            s = coerce_emotion(form, LABELS)
            assert s.labels == LABELS and s.times.tolist() == [0.0], form
            np.testing.assert_array_equal(s.weights, [[0, 1, 0, 0]])

    def test_a_blend_keeps_its_weights(self):
        s = coerce_emotion("happy=0.7,neutral=0.3", LABELS)
        np.testing.assert_allclose(s.weights[0], [0.7, 0, 0, 0.3])
        np.testing.assert_allclose(s.points[0], valence_arousal(s.weights[0], LABELS))

    @given(finite_va, finite_va)
    def test_a_point_is_kept_exactly_and_blended_by_the_kernel(self, v, a):
        s = coerce_emotion(f"valence={v!r},arousal={a!r}", LABELS)
        np.testing.assert_array_equal(s.sample_valence_arousal(3, 30.0), [[v, a]] * 3)
        np.testing.assert_allclose(s.weights[0],
                                   Emotion.from_valence_arousal(v, a, LABELS).weights)
        same = coerce_emotion({"valence": v, "arousal": a}, LABELS)
        np.testing.assert_array_equal(same.points, s.points)

    @pytest.mark.parametrize(("text", "words"), [
        ("valence=1.4,arousal=0", ["valence=1.4 is outside -1..1"]),
        ("valence=0,arousal=-1.01", ["arousal=-1.01 is outside -1..1"]),
        ("valence=3,arousal=1", ["valence=3 is outside -1..1",
                                 "old FCRBM 1..3 scale, subtract 2: valence=1"]),
        ("valence=0,arousal=2.5", ["arousal=2.5", "subtract 2: arousal=0.5"]),
        ("valence=-7,arousal=0", ["valence=-7 is outside", "give a value in -1..1"]),
        ("valence=nan,arousal=0", ["not finite"]),
        ("valence=0.5", ["both valence and arousal"]),
        ("valence=0.5,arousal=0,happy=1", ["both valence and arousal"]),
        ("valence=x,arousal=0", ["not a number"]),
    ])
    def test_points_outside_the_circumplex_show_the_fix(self, text, words):
        with pytest.raises(EmotionError) as exc:
            coerce_emotion(text, LABELS)
        assert all(w in str(exc.value) for w in words), str(exc.value)

    def test_old_scale_keyframes_show_the_conversion(self):
        with pytest.raises(EmotionError, match=r"keyframe 1.*subtract 2: valence=1"):
            coerce_emotion([{"t": 0, "emotion": "sad"}, {"t": 1, "valence": 3, "arousal": 2}],
                           LABELS)

    def test_weights_above_one_are_refused_not_scaled(self):
        for text in ("happy=1e308,sad=1e308", "happy=2", "sad=1.5,neutral=0.5"):
            with pytest.raises(EmotionError, match=r"outside 0\.\.1"):
                coerce_emotion(text, LABELS)
        with pytest.raises(EmotionError, match=r"outside 0\.\.1"):
            coerce_emotion({"happy": 3}, LABELS)

    @given(st.lists(st.floats(0, 1e308), min_size=4, max_size=4).filter(lambda w: any(w)))
    def test_any_finite_non_negative_weights_normalize(self, weights):
        w = coerce_emotion(np.array(weights), LABELS).weights[0]
        assert np.isfinite(w).all() and math.isclose(w.sum(), 1.0, rel_tol=1e-12)

    def test_labels_the_model_lacks_must_weigh_zero(self):
        wide = (*LABELS, "proud")
        s = coerce_emotion(Emotion.parse("happy=1", wide), LABELS)
        np.testing.assert_array_equal(s.weights, [[1, 0, 0, 0]])
        with pytest.raises(EmotionError, match="no emotion 'proud'"):
            coerce_emotion(Emotion.parse("proud=1", wide), LABELS)
        with pytest.raises(EmotionError, match="unknown emotion 'furious'"):
            coerce_emotion("furious", LABELS)

    def test_a_bad_type_or_file_is_an_error(self, tmp_path):
        with pytest.raises(EmotionError, match="an emotion must be"):
            coerce_emotion(3.5, LABELS)
        with pytest.raises(EmotionError, match="does not exist"):
            coerce_emotion(tmp_path / "missing.json", LABELS)

    def test_a_blend_is_constant(self):
        assert coerce_blend("valence=0,arousal=0", LABELS).dominant == "neutral"
        np.testing.assert_array_equal(coerce_blend(Emotion.one_hot("sad"), LABELS).weights,
                                      [0, 1, 0, 0])


class TestValenceArousalTrack:
    def test_point_keyframes_exactly_and_label_keyframes_by_their_mean(self):
        s = coerce_emotion([{"t": 0, "valence": 0.9, "arousal": -0.4},
                            {"t": 1, "emotion": "angry"}, {"t": 1, "valence": 0.8,
                                                          "arousal": 1.0}], LABELS)
        track = s.sample_valence_arousal(61, 30.0)
        assert track.shape == (61, 2)
        np.testing.assert_array_equal(track[0], [0.9, -0.4])
        angry = [VALENCE_AROUSAL["angry"].valence, VALENCE_AROUSAL["angry"].arousal]
        np.testing.assert_allclose(track[15], (np.array([0.9, -0.4]) + angry) / 2)
        np.testing.assert_array_equal(track[30:], [[0.8, 1.0]] * 31)
        # The label weights of a point stay the kernel blend.
        np.testing.assert_allclose(s.weights[0],
                                   Emotion.from_valence_arousal(0.9, -0.4, LABELS).weights)

    @given(st.lists(st.tuples(st.floats(0, 10), finite_va, finite_va), min_size=1, max_size=5))
    def test_the_track_stays_between_its_keyframes(self, keys):
        keys = sorted(keys)
        s = coerce_emotion([{"t": t, "valence": v, "arousal": a} for t, v, a in keys], LABELS)
        track = s.sample_valence_arousal(40, 3.0)
        points = np.array([[v, a] for _, v, a in keys])
        assert np.all(track >= points.min(0) - 1e-12) and np.all(track <= points.max(0) + 1e-12)

    def test_relabel_keeps_the_track(self):
        s = coerce_emotion("valence=0.3,arousal=0.2", ALL_LABELS)
        moved = s.relabel(ALL_LABELS[::-1])
        np.testing.assert_array_equal(moved.points, s.points)
        np.testing.assert_array_equal(moved.weights[:, ::-1], s.weights)
