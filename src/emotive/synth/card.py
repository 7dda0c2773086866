"""``README.md`` of a synthetic data set: its card.

The card of a folder made by ``emotive synth`` (the main paper's augmented data set,
Bhattacharya et al. 2020, section 5.2): the recipe and counts, how trajectories, emotions and
transitions were drawn, the checks (novelty of the trajectories against the data, the
classifier's reading, foot skate, path deviation), the licence the data set inherits from the
data the model was trained on, the files and how to load them. It is written from the recipe,
the novelty report and the manifest alone, so the same recipe gives the same card, however
many workers made it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from emotive.synth.emotions import LABELS

#: The licence of the shipped weights' training data, which the synthetic data inherits.
LICENCE = "CC BY-NC 4.0"
LICENCE_URL = "https://creativecommons.org/licenses/by-nc/4.0/"
DATA_CITATION = ("Kobayashi et al. 2023, Motion Capture Dataset for Practical Use of AI-based "
                 "Motion Editing and Stylization (arXiv:2306.08861), Bandai Namco Research "
                 "Motion Dataset")
PAPER = ("Bhattacharya et al. 2020, Generating Emotive Gaits for Virtual Agents Using "
         "Affect-Based Autoregression (ISMAR), section 5.2")


def _n(count: int, one: str, many: str | None = None) -> str:
    return f"{count} {one if count == 1 else many or one + 's'}"


def _col(manifest: Any, name: str) -> np.ndarray:
    return manifest.column(name).to_numpy(zero_copy_only=False)


def _stats(values: np.ndarray) -> str:
    values = values[np.isfinite(values)]
    if not len(values):
        return "not measured"
    return (f"mean {values.mean():.3f}, median {np.median(values):.3f}, "
            f"max {values.max():.3f}")


def _novelty(novelty: dict[str, Any], trajectories: list[dict[str, Any]]) -> list[str]:
    lines = ["### Novel trajectories", ""]
    if not novelty["checked"]:
        lines += [f"**The check against the data was skipped**: {novelty['reason']}. Run the "
                  "command again where the Bandai Namco data is found (`emotive data`) to "
                  "check the trajectories.", ""]
    else:
        fraction = novelty["match_fraction"]
        worst = max(novelty["paths"], key=lambda p: p["coverage"] if p["relative_gap"] <
                    fraction else -1.0)
        again = [p for p in novelty["paths"] if p["draw"]]
        drawn = (f" {_n(len(again), 'trajectory was', 'trajectories were')} drawn again "
                 f"because an earlier draw coincided with a clip (the draw is in the table)."
                 if again else "")
        lines += [
            f"Checked against the root paths of {novelty['clips']} locomotion clips of "
            f"{' and '.join(novelty['datasets'])}, over each trajectory's own length: a "
            f"trajectory would coincide with a clip if the clip fitted a stretch of it (or it "
            f"a stretch of the clip) within a mean gap of {fraction:.0%} of the length "
            f"compared, after the best rotation and translation, and the stretch spanned at "
            f"least {novelty['min_coverage']:.0%} of the trajectory. None coincides.{drawn} "
            f"The closest: trajectory {worst['path_id']} and `{worst['nearest_clip']}` (gap "
            f"{worst['distance_m']:.2f} m, {worst['relative_gap']:.1%} of the length "
            f"compared, over {worst['coverage']:.0%} of the trajectory).", ""]
    checks = {p["path_id"]: p for p in novelty.get("paths", [])}
    lines += ["| path | draw | length (m) | turns | turn angles (deg) | max curvature (1/m) | "
              "closest clip | gap (m) | coverage |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for t in trajectories:
        c = checks.get(t["path_id"])
        near = (f"`{c['nearest_clip']}` | {c['distance_m']:.2f} | {c['coverage']:.0%}"
                if c else "not checked | | ")
        angles = ", ".join(f"{a:+.0f}" for a in t["turn_angles_deg"])
        lines.append(f"| {t['path_id']} | {t['draw']} | {t['length_m']:.1f} | "
                     f"{t['turns']} | {angles} | "
                     f"{t['max_curvature_per_m']:.2f} | {near} |")
    return [*lines, ""]


def _classifier(manifest: Any) -> list[str]:
    kind = _col(manifest, "kind")
    perceived = _col(manifest, "perceived").astype(str)
    unsure = _col(manifest, "unsure").astype(bool)
    emotion = np.stack(_col(manifest, "emotion"))
    heaviest = np.array(LABELS)[emotion.argmax(1)]
    const = kind == "constant"
    lines = ["### What the classifier perceives", "",
             "The toolkit's perceived-emotion classifier (trained on real walks only) judged "
             "every walk: the label of its highest mean probability over 4 s windows, and "
             "whether most windows were unlike its training data (unsure).", ""]
    if const.any():
        agree = float((perceived[const] == heaviest[const]).mean())
        lines.append(f"- walks of one emotion: the perceived label is the blend's heaviest "
                     f"label for {agree:.1%} of {int(const.sum())} (the blends are novel, none "
                     "is a pure label; chance is 25%)")
    counts = ", ".join(f"{label} {int((perceived == label).sum())}" for label in LABELS)
    lines += [f"- perceived labels over all walks: {counts}",
              f"- unsure: {int(unsure.sum())} of {len(unsure)} walks ({unsure.mean():.1%})", ""]
    return lines


def _measures(manifest: Any) -> list[str]:
    return ["### Feet and path", "",
            f"- foot skate, mean horizontal speed of planted feet (m/s): "
            f"{_stats(_col(manifest, 'foot_skate'))}",
            f"- share of planted intervals sliding faster than 0.1 m/s: "
            f"{_stats(_col(manifest, 'foot_skate_ratio'))}",
            f"- root's distance from the path (m), mean per walk: "
            f"{_stats(_col(manifest, 'path_deviation'))}; largest per walk: "
            f"{_stats(_col(manifest, 'path_deviation_max'))}",
            f"- facing against the path's direction (degrees), mean per walk: "
            f"{_stats(_col(manifest, 'heading_deviation'))}", ""]


def _model_notes(manifest: Any) -> list[str]:
    """What the model could not honour of the recipe, read from the walks themselves."""
    notes = []
    if not np.isfinite(_col(manifest, "path_deviation")).any():
        notes.append("- **This model walks freely**: the walks follow no trajectory; "
                     "`path_id` only groups them as the recipe laid them out.")
    emotion = np.stack(_col(manifest, "emotion"))
    if np.allclose(emotion.max(1), 1.0):
        notes.append("- **This model makes one label at a time**: each walk expresses the "
                     "heaviest label of its novel blend, so its emotions are the data's.")
    return [*notes, ""] if notes else []


def card_text(recipe: dict[str, Any], novelty: dict[str, Any], manifest: Any,
              trajectories: list[dict[str, Any]], recipe_id: str) -> str:
    """The card (Markdown) of a finished data set.

    Args:
        recipe: the folder's recipe (``recipe.json``).
        novelty: the novelty report (``novelty.json``).
        manifest: the manifest table.
        trajectories: :meth:`Trajectory.summary
            <emotive.synth.trajectories.Trajectory.summary>` of every trajectory.
        recipe_id: the recipe's id.
    """
    n = manifest.num_rows
    kind = _col(manifest, "kind")
    frames = int(_col(manifest, "frames").sum())
    fps = float(_col(manifest, "fps")[0])
    tr, em = recipe["trajectories"], recipe["emotion_draws"]
    point = bool(recipe.get("valence_arousal_model"))
    rig = recipe["rig"]
    trained = (f"the model `{recipe['model']}` whose shipped weights were trained on"
               if not str(recipe["weights"]).startswith("none") else
               f"the model `{recipe['model']}` directly from")
    lines = [
        "# Synthesized Emotive Gaits", "",
        f"Made by `emotive synth` (recipe `{recipe_id}`) after the augmented data set of "
        f"{PAPER}: walks on trajectories not in the data with emotions not in the data, and "
        "transitions between pairs of those emotions.", "",
        "## Licence: non-commercial", "",
        f"The walks were made by {trained} the Bandai Namco Research motion data sets "
        f"({DATA_CITATION}), licensed "
        f"**{LICENCE}** ({LICENCE_URL}). This synthetic data set derives from them and "
        f"inherits that licence: **non-commercial use only, with attribution** to the Bandai "
        "Namco data sets (citation above) and to emotive.", "",
        "## Recipe and counts", "",
        f"- {_n(recipe['paths'], 'trajectory', 'trajectories')} x "
        f"{_n(recipe['emotions'], 'emotion')} = {_n(int((kind == 'constant').sum()), 'walk')} of "
        f"one emotion, plus {_n(recipe['paths'], 'trajectory', 'trajectories')} x "
        f"{_n(recipe['transitions'], 'pair')} = "
        f"{_n(int((kind == 'transition').sum()), 'transition')}: **{n} walks** of "
        f"{recipe['seconds']:g} s ({frames:,} frames at "
        f"{fps:g} fps, {frames / fps / 3600:.2f} hours)",
        f"- model `{recipe['model']}` (weights {recipe['weights']}); rig: "
        f"{'the model' + chr(39) + 's own' if rig is None else rig['name']}; seed "
        f"{recipe['seed']}; {recipe['shard_size']} walks per shard; files: "
        f"{', '.join(recipe['formats'])}",
        f"- made with emotive {recipe['emotive']}", "",
        "Every walk is a function of the recipe and its sample index (`sample_id`): the "
        "shards are fixed index ranges and each is stepped as one batch, so the data set is "
        "the same, byte for byte, however many workers or machines made it (same library "
        "versions and CPU kind).", "",
        "## How the walks were drawn", "",
        f"- **Trajectories**: smooth ground paths from the origin facing +Z, "
        f"{tr['length_per_second_m'][0]:g}-{tr['length_per_second_m'][1]:g} m per second of "
        f"walk plus {tr['length_margin_m']:g} m (no walker reaches the end); straight "
        f"stretches of {tr['straight_m'][0]:g}-{tr['straight_m'][1]:g} m between turns of "
        f"{tr['turn_angle_deg'][0]:g}-{tr['turn_angle_deg'][1]:g} degrees to a random side at "
        f"curvature {tr['curvature_per_m'][0]:g}-{tr['curvature_per_m'][1]:g} 1/m, with "
        f"{tr['ramp_m']:g} m curvature ramps.",
        ("- **Emotions**: valence/arousal points uniform in the disc of radius "
         f"{em['va_radius']:g}, at least {em['va_clearance']:g} from every labelled style of "
         "the data" if point else
         f"- **Emotions**: blends over {', '.join(em['labels'])} uniform on the simplex, no "
         f"weight above {em['max_weight']:g} (away from the data's pure labels)") +
        "; the same emotions on every trajectory.",
        f"- **Transitions**: on each trajectory, disjoint pairs of those emotions (drawn "
        f"without replacement); the emotion changes linearly over {em['ramp_seconds']:g} s "
        f"(at most a fifth of the walk) from a time drawn in "
        f"{em['switch_share'][0]:.0%}-{em['switch_share'][1]:.0%} of the walk.", "",
        *_model_notes(manifest),
        "## Checks", "",
        *_novelty(novelty, trajectories), *_classifier(manifest), *_measures(manifest),
        "## Files", "",
        "- `manifest.parquet`: one row per walk (ids, trajectory, emotion weights over "
        f"{', '.join(LABELS)}, valence/arousal, the transition pair and time, seeds, the "
        "sha256 of the walk's arrays, the classifier's reading, foot skate, path deviation).",
        "- `shards/shard-NNNNN.npz`: per shard, float32 arrays of its walks: `rotations` "
        "(local, w x y z), `root` (the root joint's translation), `world` (joints then end "
        "sites, metres, Y up), `emotion`, `valence_arousal`, their paths (`path_index`, "
        "`path_offsets`, `path_points`), and the rig.",
        *([f"- `{fmt}/walk-NNNNNN.{fmt}`: each walk as {fmt.upper()}." for fmt in
           recipe["formats"][1:]]),
        "- `recipe.json`, `novelty.json`: the recipe and the trajectories' check.", "",
        "## Loading", "",
        "```python",
        "import pandas as pd",
        "from emotive.synth import SyntheticGaits",
        "",
        "manifest = pd.read_parquet(\"manifest.parquet\")    # one row per walk",
        "walks = SyntheticGaits(\".\")                       # a torch Dataset",
        "item = walks[0]                                   # tensors: rotations (T, J, 4), ...",
        "motion = walks.motion(0)                          # an emotive Motion (write_bvh, ...)",
        "```", "",
    ]
    return "\n".join(lines)
