"""The classifier study's mechanics on a tiny synthetic set and a tiny recipe.

The synthetic set (5 walks of 4 s: 4 blends and a transition on one path) is made in this
process without Ray; the "real" clips of the mechanics tests are role tracks of those walks
given Bandai names, styles and splits, so everything but the last test runs without the data.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from cli_helpers import run_main
from emotive.eval.classifier import ClassifierConfig, track_features
from emotive.eval.classifier_training import ClipTrack, split_features, train_classifier
from emotive.synth import engine, synthesize
from emotive.synth.classifier_data import SynthMix, synthetic_clips, walk_clips
from emotive.synth.classifier_mix import MixedSampler, train_mixed
from emotive.synth.classifier_stats import clip_bootstrap, macro_f1, mcnemar_windows, seed_tests
from emotive.synth.classifier_study import StudyConfig, parse_seeds, run_study
from emotive.synth.recipe import Recipe, SynthError

TINY = ClassifierConfig(epochs=2, steps_per_epoch=3, batch_size=32, channels=8, blocks=1,
                        augment_copies=1, max_seconds=2.0)
#: Fake real clips: (data set, style, clips per split).
STYLES = (("bandai-namco-1", "happy"), ("bandai-namco-1", "sad"), ("bandai-namco-1", "angry"),
          ("bandai-namco-1", "normal"), ("bandai-namco-2-locomotion", "normal"),
          ("bandai-namco-2-locomotion", "active"))


def _in_process(todo, task, args, write, workers=None, address=None, progress=None):
    """``engine.run_shards`` without Ray: the same shard function, in this process."""
    shards = walks = 0
    for shard in todo:
        result = task(*args, shard)
        write(result)
        shards, walks = shards + 1, walks + len(result.rows)
    return engine.RunStats(shards, walks, 1.0, 1, "in-process")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("synth") / "tiny"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(engine, "run_shards", _in_process)
        synthesize(out, Recipe(paths=1, emotions=4, transitions=1, seconds=4.0, shard_size=5),
                   progress=False)
    return out


@pytest.fixture(scope="module")
def role_tracks(folder):
    """``(T, 21, 3)`` role tracks of the 5 synthetic walks, as the classifier reads them."""
    from emotive.core.roles import resolve_roles
    from emotive.eval.classifier import judge_joints
    from emotive.synth import SyntheticGaits

    walks = SyntheticGaits(folder, fields=("world",))
    sk = walks.motion(0).skeleton
    joints = judge_joints(sk, resolve_roles(sk))
    return [walks[i]["world"].numpy()[:, joints] for i in range(len(walks))]


@pytest.fixture(scope="module")
def tracks(role_tracks):
    """Bandai-named clips made of the synthetic walks, 3 per style (one per split); the frame
    rate they claim changes with the style, so the styles move at different speeds."""
    out = []
    for k, (dataset, style) in enumerate(STYLES):
        for j, split in enumerate(("train", "val", "test")):
            points = role_tracks[(k + j) % len(role_tracks)]
            out.append(ClipTrack(f"{dataset}_walk_{style}_{j:03d}", dataset, "walk", style,
                                 split, points, 30.0 * (0.8 + 0.1 * k)))
    return out


@pytest.fixture(scope="module")
def data(tracks):
    return split_features(tracks, TINY)


@pytest.fixture(scope="module")
def synthetic(folder):
    return synthetic_clips(folder, TINY, SynthMix(), 0)


def test_synthetic_walks_become_clips_with_the_emotion_at_each_frame(folder, synthetic):
    assert {c.variant for c in synthetic} == {0, 1} and len(synthetic) == 10
    assert {c.kind for c in synthetic} == {"constant", "transition"}
    for c in synthetic:
        assert c.features.shape[1] == 152 and abs(len(c.features) - 60) <= 1
        assert c.emotion.shape == (len(c.features), 4) and c.valence_arousal.shape[1] == 2
        np.testing.assert_allclose(c.emotion.sum(-1), 1.0, atol=1e-5)
        assert c.emotion.max() <= 0.7 + 1e-5   # novel blends, no pure label
    walk = next(c for c in synthetic if c.kind == "transition" and c.variant == 0)
    assert not np.allclose(walk.emotion[0], walk.emotion[-1], atol=1e-3)
    # Constant before the switch (40-60 % of the walk), constant after the 1 s ramp.
    np.testing.assert_allclose(walk.emotion[:20], walk.emotion[:1].repeat(20, 0), atol=1e-6)
    np.testing.assert_allclose(walk.emotion[-5:], walk.emotion[-1:].repeat(5, 0), atol=1e-6)
    # An augmented variant keeps the emotion at the same second.
    variant = next(c for c in synthetic if c.sample_id == walk.sample_id and c.variant == 1)
    n = min(len(walk.emotion), len(variant.emotion))
    np.testing.assert_allclose(variant.emotion[:n], walk.emotion[:n], atol=1e-6)


def test_the_shuffled_control_moves_targets_between_walks(folder, synthetic):
    shuffled = synthetic_clips(folder, TINY, SynthMix(target="shuffled"), 0)
    assert [(c.name, c.variant) for c in shuffled] == [(c.name, c.variant) for c in synthetic]
    moved = 0
    for a, b in zip(synthetic, shuffled, strict=True):
        np.testing.assert_array_equal(a.features, b.features)
        assert b.emotion.shape == a.emotion.shape
        moved += not np.allclose(a.emotion, b.emotion)
    assert moved > 0
    own = sorted(tuple(c.emotion[0].round(5)) for c in synthetic if c.variant == 0)
    assert sorted(tuple(c.emotion[0].round(5)) for c in shuffled if c.variant == 0) == own


def test_walk_clips_resample_the_targets_like_the_features(role_tracks):
    points = role_tracks[0]
    t = np.arange(len(points)) / 30.0
    emotion = np.stack([t / t[-1], 1 - t / t[-1], 0 * t, 0 * t], 1)
    clip = walk_clips(points, 30.0, emotion, emotion[:, :2], TINY, 0,
                      np.random.default_rng(0))[0]
    assert len(clip.emotion) == len(clip.features) == 60
    np.testing.assert_allclose(clip.emotion[:, 0], np.arange(60) / 15.0 / t[-1], atol=1e-6)
    np.testing.assert_allclose(clip.features, track_features(points, 30.0, TINY))


def test_share_zero_is_the_shipped_recipe_weight_for_weight(data, synthetic):
    ref = train_classifier(TINY, data=data)
    for mixed in (train_mixed(TINY, data), train_mixed(TINY, data, synthetic, SynthMix(0.0))):
        for k, v in ref.net.state_dict().items():
            assert torch.equal(v, mixed.net.state_dict()[k]), k
        assert mixed.temperature == ref.temperature
        assert mixed.unsure_distance == ref.unsure_distance
        assert json.dumps(mixed.metrics["test"]) == json.dumps(ref.metrics["test"])


def test_batches_mix_a_fixed_share_and_synthetic_stays_in_training(data, synthetic):
    sampler = MixedSampler(data["train"], synthetic, TINY, SynthMix(share=0.25))
    x, y, style, _, q = sampler.draw(np.random.default_rng(0), 8)
    assert x.shape[0] == 8 and sampler.synthetic_rows(8) == 2
    assert np.all(y[6:] == -1) and np.all(style[6:] == -1)
    np.testing.assert_allclose(q[6:].sum(-1), 1.0, atol=1e-6)
    assert not q[:6].any()
    hard = MixedSampler(data["train"], synthetic, TINY, SynthMix(share=0.5, target="heaviest"))
    q = hard.draw(np.random.default_rng(0), 8)[4]
    assert set(np.unique(q[4:])) == {0.0, 1.0} and np.all(q[4:].sum(-1) == 1)
    leaked = {**data, "val": [*data["val"], synthetic[0]]}
    with pytest.raises(SynthError, match="validation and test stay real"):
        train_mixed(TINY, leaked, synthetic)


def test_study_is_paired_reproducible_and_in_range(folder, tracks):
    study = StudyConfig(seeds=(0, 1), mix=SynthMix(share=0.25), resamples=200)
    report = run_study(folder, TINY, study, tracks=tracks)
    assert [(r["seed"], r["arm"]) for r in report["runs"]] == [
        (0, "real"), (0, "real+synthetic"), (1, "real"), (1, "real+synthetic")]
    assert report["synthetic"]["walks"] == 5 and report["synthetic"]["clips"] == 10
    assert [r["synthetic"]["clips"] for r in report["runs"]] == [0, 10, 0, 10]
    for run in report["runs"]:
        assert set(run["held_out"]) == {"bandai-namco-1", "bandai-namco-2-locomotion", "all"}
        for d, result in run["held_out"].items():
            for m in ("window_accuracy", "balanced_accuracy", "macro_f1", "ece", "unsure_rate"):
                assert 0.0 <= result[m] <= 1.0, (d, m)
            # The same held-out windows in every run, real clips only.
            first = report["runs"][0]["held_out"][d]["per_window"]
            assert result["per_window"]["clip"] == first["clip"]
            assert all(c.startswith(d if d != "all" else "bandai") for c in first["clip"])
    assert report["test_set"]["bandai-namco-1"]["labelled_clips"] == 4
    for d in ("bandai-namco-1", "bandai-namco-2-locomotion", "all"):
        paired = report["paired"][d]
        assert paired["mcnemar"]["windows"] == 2 * report["test_set"][d]["windows"]
        assert 0.0 <= paired["mcnemar"]["p"] <= 1.0
        boot = paired["clip_bootstrap"]
        assert boot["low"] <= boot["difference"] <= boot["high"]
        summary = report["summary"][d]["window_accuracy"]["real"]
        assert len(summary["values"]) == 2
    assert isinstance(report["decision"]["better"], bool)
    json.dumps(report)   # plain JSON types throughout
    again = run_study(folder, TINY, replace(study, seeds=(1,)), tracks=tracks)
    assert json.dumps(again["runs"][1]["held_out"]) == json.dumps(report["runs"][3]["held_out"])


def test_statistics_match_the_libraries():
    sklearn = pytest.importorskip("sklearn.metrics")
    truth = np.array([0, 0, 1, 1, 2, 2, 2, 3])
    pred = np.array([0, 1, 1, 1, 2, 0, 2, 1])
    confusion = np.zeros((4, 4), int)
    np.add.at(confusion, (truth, pred), 1)
    assert macro_f1(confusion) == pytest.approx(
        sklearn.f1_score(truth, pred, labels=[0, 1, 2, 3], average="macro"))
    only_neutral = np.zeros((4, 4), int)
    only_neutral[3] = [0, 2, 0, 8]
    assert macro_f1(only_neutral) == pytest.approx(2 * 8 / (2 * 8 + 2))
    a = np.array([True] * 10 + [False] * 6)
    b = np.array([True] * 8 + [False] * 2 + [True] * 5 + [False])
    mc = mcnemar_windows(a, b)
    assert (mc["only_a_right"], mc["only_b_right"]) == (2, 5) and 0 < mc["p"] < 1
    same = seed_tests([0.5, 0.6, 0.7], [0.5, 0.6, 0.7])
    assert np.isnan(same["t_test"]["p"]) and same["wilcoxon"]["p"] == 1.0
    shifted = seed_tests([0.5, 0.25, 0.75], [0.75, 0.5, 1.0])
    assert shifted["difference_mean"] == 0.25 and np.isnan(shifted["t_test"]["p"])
    assert shifted["t_test"]["notes"] == ["every seed's difference is the same"]
    # Nearly equal differences: SciPy's warning is kept with the result, not raised.
    near = seed_tests([0.5, 0.6, 0.7], [0.6, 0.7, 0.8])
    assert near["t_test"]["notes"] and not np.isnan(near["wilcoxon"]["p"])
    boot = clip_bootstrap(["a", "a", "b", "c"], [True, False, True, False],
                          [True, True, True, True], 300)
    assert boot["clips"] == 3 and boot["low"] <= 0.5 <= boot["high"]


@pytest.mark.parametrize(("text", "seeds"), [("0,1,2", (0, 1, 2)), ("0-3", (0, 1, 2, 3)),
                                             (" 4, 0-1", (4, 0, 1))])
def test_seeds_parse(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "a", "1,1", "3-1", "-1", "0.5"])
def test_bad_seeds_are_a_typed_error(text):
    with pytest.raises(SynthError, match="--seeds"):
        parse_seeds(text)


def test_bad_mix_and_folders_are_typed_errors(tmp_path, tracks):
    with pytest.raises(SynthError, match="share 1"):
        SynthMix(share=1)
    with pytest.raises(SynthError, match="choose one of blend, heaviest"):
        SynthMix(target="argmax")
    with pytest.raises(SynthError, match="--share 0"):
        StudyConfig(mix=SynthMix(share=0))
    with pytest.raises(SynthError, match="no such folder; make it first"):
        run_study(tmp_path / "missing", TINY, StudyConfig(), tracks=tracks)
    with pytest.raises(SynthError, match=r"no manifest\.parquet"):
        run_study(tmp_path, TINY, StudyConfig(), tracks=tracks)


@pytest.mark.parametrize(("args", "words"), [
    (["--synth", "{tmp}/missing"], ["--synth", "no such folder", "emotive synth --out"]),
    (["--synth", "{tmp}", "--seeds", "x"], ["--seeds 'x'", "e.g. --seeds 0,1,2"]),
    (["--synth", "{tmp}", "--target", "soft"], ["synthetic target 'soft'", "blend"]),
    (["--synth", "{tmp}", "--share", "0"], ["--share 0", "above 0"]),
])
def test_cli_bad_input_is_one_line_and_writes_nothing(monkeypatch, capsys, tmp_path, args,
                                                      words):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    code, out, err = run_main(monkeypatch, capsys, "synth", "classifier-study", *args,
                              "--out", tmp_path / "report.json")
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert all(w in lines[0] for w in words), lines[0]
    assert not (tmp_path / "report.json").exists() and not out


def test_cli_refuses_a_report_that_is_not_json(monkeypatch, capsys, tmp_path):
    code, _, err = run_main(monkeypatch, capsys, "synth", "classifier-study", "--synth",
                            tmp_path, "--out", tmp_path / "report.txt")
    assert code == 2 and "--out" in err and ".json" in err


def test_synth_still_makes_sets_and_lists_the_study(monkeypatch, capsys):
    code, _, err = run_main(monkeypatch, capsys, "synth")
    assert code == 2 and "Missing option '--out'" in err
    code, out, _ = run_main(monkeypatch, capsys, "synth", "--help")
    assert code == 0 and "classifier-study" in out and "--transitions" in out
    code, _, err = run_main(monkeypatch, capsys, "synth", "--out", "x", "classifier-study")
    assert code == 2 and "--out belongs to `emotive synth` itself" in err


@pytest.mark.data
def test_the_real_study_holds_out_the_shipped_test_windows(bandai1_dir, bandai2_dir, folder):
    quick = replace(ClassifierConfig(), epochs=1, steps_per_epoch=2, batch_size=8,
                    augment_copies=0)
    report = run_study(folder, quick, StudyConfig(seeds=(0,), resamples=100))
    test = report["test_set"]
    # The shipped classifier's model card: 13 windows of 4 labelled clips, 36 of 14.
    assert (test["bandai-namco-1"]["windows"], test["bandai-namco-1"]["labelled_clips"]) == (13, 4)
    assert (test["bandai-namco-2-locomotion"]["windows"],
            test["bandai-namco-2-locomotion"]["labelled_clips"]) == (36, 14)
    assert all(n.startswith(("dataset-1_", "dataset-2_"))
               for n in report["runs"][0]["held_out"]["all"]["per_window"]["clip"])
