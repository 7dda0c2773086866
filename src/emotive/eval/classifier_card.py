"""The model card of the perceived-emotion classifier, written from its recorded metrics.

The metrics are those :func:`emotive.eval.classifier_training.train_classifier` records
(``val``, ``test``, ``test_by_dataset``) plus, when measured, ``leave_one_studio_out``,
``studio_proxy``, ``unsure`` and ``train_seconds`` and ``notes`` (see ``emotive train classifier``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict

from emotive.data.registry import get_dataset
from emotive.eval.classifier import SHARED_STYLE_OF, EmotionClassifier

#: The shared styles as each data set spells them, for the card.
_SPELLINGS = ("normal", "active", "feminine", "masculinity ~ masculine", "tired ~ exhausted",
              "old ~ elderly", "childish ~ youthful")


def _f(value: float, digits: int = 3) -> str:
    return "n/a" if value != value else f"{value:.{digits}f}"  # NaN is not equal to itself


def _labels_table(result: dict) -> list[str]:
    labels = result["labels"]
    lines = [
        f"- windows: {result['windows']} from {result['clips']} labelled clips",
        f"- window accuracy: {_f(result['window_accuracy'])}; clip accuracy: "
        f"{_f(result['clip_accuracy'])}; balanced accuracy: {_f(result['balanced_accuracy'])}",
        "- per label: " + ", ".join(f"{k} {v:.2f}" for k, v in result["per_label"].items()),
        f"- ECE (10 bins): {_f(result['ece_uncalibrated'])} before temperature scaling, "
        f"{_f(result['ece'])} after",
        f"- shared-style head: {_f(result['style_accuracy'])} window accuracy over "
        f"{result['style_windows']} windows (balanced {_f(result['style_balanced_accuracy'])}); "
        f"valence/arousal sign agreement {_f(result['va_sign_agreement'])}; unsure "
        f"{_f(result['unsure_rate'])} of {result['all_windows']} windows",
        "",
        "| true \\ perceived | " + " | ".join(labels) + " |",
        "|---|" + "---:|" * len(labels),
    ]
    for label, row in zip(labels, result["confusion"], strict=True):
        if sum(row):
            lines.append(f"| {label} | " + " | ".join(str(v) for v in row) + " |")
    return lines


def _loso(loso: dict) -> list[str]:
    out = [
        "## Leave one studio out",
        "",
        "Trained on one data set with the same recipe (label head where it has labels, "
        "valence/arousal head on every style, shared-style head on the seven styles both hold: "
        + ", ".join(_SPELLINGS) + "), then measured on every locomotion clip of the other "
        "data set's shared styles (all its splits, none seen in training). Dataset 2 has no "
        "happy, sad or angry, so across studios we report: the 7-way shared-style accuracy "
        "(chance 0.14), the sign agreement of valence and arousal with the style's circumplex "
        "point (styles off the axes), and, for the model trained on dataset 1, how often the "
        "other studio's `normal` clips read as neutral.",
        "",
        "| trained on | tested on | style accuracy (balanced) | per style | "
        "valence/arousal signs | neutral accuracy on normal |",
        "|---|---|---:|---|---:|---:|",
    ]
    for entry in loso.values():
        r = entry["result"]
        neutral = r["per_label"].get("neutral", float("nan"))
        out.append(
            f"| {entry['trained_on']} | {entry['tested_on']} | {_f(r['style_accuracy'])} "
            f"({_f(r['style_balanced_accuracy'])}) | "
            + ", ".join(f"{k} {v:.2f}" for k, v in r["per_style"].items())
            + f" | {_f(r['va_sign_agreement'])} | {_f(neutral)} |"
        )
    return [*out, ""]


def _proxy(loso: dict, proxy: dict | None) -> list[str]:
    entry = next((e for e in loso.values() if e["trained_on"] == "bandai-namco-1"), None)
    if entry is None:
        return []
    rows = [("as recorded", entry["mean_probabilities"])]
    if proxy:
        rows.append(("on other rigs", proxy))
    out = [
        "## Another studio's depressed and angry walks: the proxy",
        "",
        "No other studio's clips labelled sad or angry are at hand. The closest honest proxy: "
        "the model trained on dataset 1 only reads dataset 2 (another capture session, "
        "actors and rig, never seen in that training), where `exhausted` stands for a "
        "depressed walk and `active` for the high-arousal one (the nearest to angry that "
        "dataset 2 holds); `normal` is neutral. \"On other rigs\" puts every such clip on "
        "other proportions, role layouts, heights, mirror images and frame rates "
        "(two variants each of `emotive.eval.classifier_augment.augment`, other draws than "
        "training's). Mean calibrated probabilities over 4 s windows:",
        "",
        "| clips | style | P(happy) | P(sad) | P(angry) | P(neutral) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for name, table in rows:
        for style in ("exhausted", "normal", "active"):
            if style in table:
                p = table[style]
                out.append(f"| {name} | {style} | " + " | ".join(
                    f"{p[k]:.3g}" for k in ("happy", "sad", "angry", "neutral")) + " |")
    out.append("")
    for name, table in rows:
        if not {"exhausted", "normal", "active"} <= set(table):
            continue
        sad = {s: table[s]["sad"] for s in ("exhausted", "normal", "active")}
        angry = {s: table[s]["angry"] for s in ("exhausted", "normal", "active")}
        margin = sad["exhausted"] - max(sad["normal"], sad["active"])
        angrier = angry["active"] > max(angry["normal"], angry["exhausted"])
        out.append(
            f"- {name}: exhausted reads sadder than normal and active: "
            f"{'yes' if margin > 0 else 'no'} (by {margin:+.3f}); "
            f"active reads angrier than exhausted and normal: {'yes' if angrier else 'no'}"
            + (" (but P(angry) stays below 0.01 everywhere: no meaningful ranking)"
               if max(angry.values()) < 0.01 else "")
        )
    return [*out, ""]


def _unsure(rates: dict, quantile: float) -> list[str]:
    held = rates["held_out"]
    return [
        "## Unsure",
        "",
        "A window is unsure when the Mahalanobis distance of its pooled embedding from the "
        f"training windows' embeddings exceeds their {quantile:.0%} quantile. Share of unsure "
        f"windows over the {rates['clips']} held-out test clips and probes made from them:",
        "",
        "| input | unsure |",
        "|---|---:|",
        f"| held-out clips, 4 s windows | {_f(held['4s'])} |",
        f"| held-out clips, 0.8 s windows | {_f(held['0.8s'])} |",
        *(f"| held-out {d}, 4 s windows | {_f(v)} |"
          for d, v in rates["held_out_by_dataset"].items()),
        f"| a still figure spinning one turn a second | {_f(rates['spinning'])} |",
        f"| random joint noise | {_f(rates['joint_noise'])} |",
        "",
    ]


def classifier_card(model: EmotionClassifier, clips: dict[str, Sequence[str]],
                    weights: tuple[str, str] | None = None) -> str:
    """Markdown model card of a trained perceived-emotion classifier.

    Args:
        model: the classifier with its ``metrics`` (see the module docstring).
        clips: clip names by split, as trained (augmented variants not repeated).
        weights: ``(file name, sha256)`` of the saved weights: the card's fingerprint line,
            which a shipped copy is checked against when loaded.
    """
    cfg, m = model.config, model.metrics
    out = [
        "# Perceived-emotion classifier",
        "",
        f"A {cfg.architecture} network that reads windows of 0.8 s (about one stride) or more "
        "of any humanoid clip (positions of the 21 joint roles in the body frame, read at "
        "joints only: hand tips at the wrists, toes at the toe joint below the ankle, so end "
        "sites and helper bones do not matter; their velocities, the 18 affective features "
        f"and 8 movement features, at {cfg.fps:g} fps) "
        f"and gives calibrated probabilities over {', '.join(cfg.labels)}, a valence/arousal "
        "estimate, and an explicit *unsure* when the motion is unlike its training data. It "
        "stands in for human observers when the project's generators are evaluated; it was "
        "trained on real motion only. Code: `emotive.eval.classifier`; retrain with "
        "`emotive train classifier --out DIR`.",
        "",
        "## Training data and license",
        "",
        *(f"- {get_dataset(name).attribution}" for name in cfg.datasets),
        "",
        "The weights are derived from CC BY-NC 4.0 data: use them for non-commercial "
        "purposes only.",
        "",
        "Locomotion clips only (dataset 1: walk, walk-back, walk-left, walk-right, run, dash; "
        "dataset 2: walk, walk-turn-left, walk-turn-right, run), every style, split by clip per "
        "data set (seed 0, 10 % validation, 10 % test per style). How the styles are used:",
        "",
        "- **label head** (happy, sad, angry, neutral): dataset 1 happy, sad, angry and normal, "
        "and dataset 2 normal, as neutral. The other styles are left out of the label loss: "
        "calling a proud or an elderly walk one of four emotions would teach the head labels "
        "no observer gave.",
        "- **valence/arousal head**: every clip of every style, at its point of "
        "`emotive.data.circumplex.VALENCE_AROUSAL` (squared error); many of those points are "
        "the project's estimates, not measured ratings.",
        "- **shared-style head**: the seven styles both data sets hold ("
        + ", ".join(_SPELLINGS) + "; "
        + f"{len(set(SHARED_STYLE_OF))} spellings in all), for the leave-one-studio-out test.",
        "",
        "Every training clip also enters as "
        f"{cfg.augment_copies} augmented variants (`emotive.eval.classifier_augment`): role "
        "layouts (spine, chest and neck points slid along the spine, shoulders toward the neck, "
        "toes toward the ankles, chest and hand-tip fallbacks), segment proportions (legs, arms, "
        "spine, widths), standing height 1.4-2.0 m, mirror images, and source frame rates "
        "24/30/60/120 fps before the classifier's own resampling. Temperature scaling on the "
        f"validation windows (T = {model.temperature:.3f}).",
        "",
        *(f"- {split} ({len(names)} clips): " + ", ".join(names) for split, names in
          clips.items()),
        "",
        "## Config",
        "",
        "```",
        *(f"{k} = {v!r}" for k, v in asdict(cfg).items()),
        "```",
        "",
        "## Measured",
        "",
        "Held-out clips in 4 s windows with a 1 s hop (a shorter clip is one window).",
        "",
    ]
    for name, result in m.get("test_by_dataset", {}).items():
        out += [f"### Test clips of {name}", "", *_labels_table(result), ""]
    out += ["### Validation clips (epoch choice and temperature)", "",
            *_labels_table(m["val"]), ""]
    if "leave_one_studio_out" in m:
        out += _loso(m["leave_one_studio_out"])
        out += _proxy(m["leave_one_studio_out"], m.get("studio_proxy"))
    if "unsure" in m:
        out += _unsure(m["unsure"], cfg.unsure_quantile)
    if "train_seconds" in m:
        trained = ("features, this model and the two leave-one-studio-out models"
                   if "leave_one_studio_out" in m else "features and this model")
        out += [f"Training ({trained}) took {m['train_seconds'] / 60:.1f} min on the CPU that "
                "wrote this card.", ""]
    if m.get("notes"):
        out += ["## Notes on this file", "", *(f"- {note}" for note in m["notes"]), ""]
    out += [
        "## Limits",
        "",
        "Dataset 1 holds seven locomotion clips per style (one actor per style), so the "
        "happy, sad and angry test numbers rest on one clip each and are uncertain by tens "
        "of points; dataset 2 adds many neutral walks but no other emotion. The temperature "
        "is fitted on a validation split that is mostly neutral windows. Both data sets come "
        "from one company's capture pipeline; the \"other studio\" tests above are a proxy, "
        "not clips of another studio. Motion far from walking and running (gestures, dance, "
        "fights) is outside what it has seen and should read as unsure.",
        "",
    ]
    if weights is not None:
        out += [
            "## Weights fingerprint",
            "",
            "Loading a weight file of this folder checks its sha256 against its line below "
            "and refuses a file that differs (damaged or replaced: reinstall emotive). "
            "Checkpoints you train have no card; they rely on their archive's CRC-32 and the "
            "tensor checks instead.",
            "",
            f"- sha256 of `{weights[0]}`: `{weights[1]}`",
            "",
        ]
    return "\n".join(out)
