"""The data sets the toolkit knows: where they come from, their license and their archives.

Each entry names one packed archive (``.tar.gz``) with its sha256, the folder it unpacks to and
the labels found in it. The archives are repackaged from the public upstream repository
`BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset
<https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset>`_ (Kobayashi et
al. 2023, arXiv:2306.08861), licensed CC BY-NC 4.0: non-commercial use only, with attribution.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from emotive.errors import DataError

UPSTREAM_REPOSITORY = "BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset"
UPSTREAM_URL = f"https://github.com/{UPSTREAM_REPOSITORY}"
LICENSE = "CC BY-NC 4.0"
LICENSE_URL = "https://creativecommons.org/licenses/by-nc/4.0/"
CITATION = (
    "Kobayashi, M. et al. (2023). Motion Capture Dataset for Practical Use of AI-based Motion "
    "Editing and Stylization. arXiv:2306.08861"
)


@dataclass(frozen=True)
class DatasetInfo:
    """One registered data set.

    Attributes:
        name: registry name used on the command line (``bandai-namco-1``).
        title: the data set's own name.
        archive: file name of the packed archive.
        sha256: hex sha256 of the archive.
        folder: the single top-level folder the archive unpacks to.
        contents: content (action) names in the order of ``cfg/content_label.txt``.
        styles: style names in the order of ``cfg/style_label.txt``.
        locomotion: the contents that are locomotion (walking, running and their variants).
        clips: number of BVH clips in the archive.
        upstream: where users outside this project get the data.
        license: license of the data.
        license_url: the license text.
        citation: the paper to cite.
    """

    name: str
    title: str
    archive: str
    sha256: str
    folder: str
    contents: tuple[str, ...]
    styles: tuple[str, ...]
    locomotion: tuple[str, ...]
    clips: int
    upstream: str = UPSTREAM_URL
    license: str = LICENSE
    license_url: str = LICENSE_URL
    citation: str = CITATION

    @property
    def attribution(self) -> str:
        """The notice to show whenever the data is fetched or redistributed."""
        return (
            f"{self.title} by Bandai Namco Research Inc. ({self.upstream}), licensed {self.license}"
            f" ({self.license_url}): non-commercial use only, credit the authors. "
            f"Cite: {self.citation}."
        )


REGISTRY: dict[str, DatasetInfo] = {
    "bandai-namco-1": DatasetInfo(
        name="bandai-namco-1",
        title="Bandai-Namco-Research-Motiondataset-1",
        archive="bandai-namco-motion-1.tar.gz",
        sha256="429857e227f13ee173cd044f9a0f76cb6e6109252c4a19b0b01672e2e817af11",
        folder="Bandai-Namco-Research-Motiondataset-1",
        contents=(
            "walk", "run", "dash", "walk-back", "walk-left", "walk-right", "bow", "bye",
            "guide", "byebye", "respond", "call", "punch", "kick", "slash", "dance-long",
            "dance-short",
        ),
        styles=(
            "normal", "happy", "sad", "angry", "proud", "not-confident", "masculinity",
            "feminine", "childish", "old", "tired", "active", "musical", "giant", "chimpira",
        ),
        locomotion=("walk", "walk-back", "walk-left", "walk-right", "run", "dash"),
        clips=174,
    ),
    "bandai-namco-2-locomotion": DatasetInfo(
        name="bandai-namco-2-locomotion",
        title="Bandai-Namco-Research-Motiondataset-2 (locomotion part)",
        archive="bandai-namco-motion-2-locomotion.tar.gz",
        sha256="a3f9fd8837429e4ade59b03681e1c47664957ed69e731a1fa315d0cf5f36a2d7",
        folder="Bandai-Namco-Research-Motiondataset-2",
        contents=(
            "walk", "walk-turn-left", "walk-turn-right", "run", "wave-both-hands",
            "wave-left-hand", "wave-right-hand", "raise-up-both-hands", "raise-up-left-hand",
            "raise-up-right-hand",
        ),
        styles=("active", "elderly", "exhausted", "feminine", "masculine", "normal", "youthful"),
        locomotion=("walk", "walk-turn-left", "walk-turn-right", "run"),
        clips=962,
    ),
}


def dataset_names() -> tuple[str, ...]:
    """Registry names of every known data set."""
    return tuple(REGISTRY)


def get_dataset(name: str | DatasetInfo) -> DatasetInfo:
    """The registry entry called ``name`` (an entry passes through unchanged).

    Raises:
        DataError: no data set has that name; the message lists the known names.
    """
    if isinstance(name, DatasetInfo):
        return name
    try:
        return REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(name, REGISTRY, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise DataError(
            f"unknown data set {name!r}{hint}; known data sets: {', '.join(REGISTRY)} "
            "(see `emotive data list`)"
        ) from None
