"""The registry matches the shared data README and names source and license."""

from __future__ import annotations

import re

import pytest

from emotive.data import registry
from emotive.data.registry import get_dataset
from emotive.errors import DataError


def test_both_datasets_registered():
    assert set(registry.dataset_names()) >= {"bandai-namco-1", "bandai-namco-2-locomotion"}
    one = get_dataset("bandai-namco-1")
    two = get_dataset("bandai-namco-2-locomotion")
    assert (one.archive, one.folder) == (
        "bandai-namco-motion-1.tar.gz", "Bandai-Namco-Research-Motiondataset-1"
    )
    assert (two.archive, two.folder) == (
        "bandai-namco-motion-2-locomotion.tar.gz", "Bandai-Namco-Research-Motiondataset-2"
    )
    assert set(one.locomotion) == {"walk", "walk-back", "walk-left", "walk-right", "run", "dash"}
    for info in (one, two):
        assert re.fullmatch(r"[0-9a-f]{64}", info.sha256)
        assert set(info.locomotion) <= set(info.contents)


def test_checksums_match_shared_readme(shared_data):
    text = (shared_data / "README.md").read_text()
    listed = dict((f, h) for h, f in re.findall(r"([0-9a-f]{64})\s+(\S+\.tar\.gz)", text))
    for name in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        info = get_dataset(name)
        assert listed[info.archive] == info.sha256
        assert f"`{info.folder[:-1]}N/`" in text


def test_source_and_license_in_attribution():
    for info in registry.REGISTRY.values():
        assert info.upstream == (
            "https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset"
        )
        assert info.license == "CC BY-NC 4.0"
        for piece in ("CC BY-NC 4.0", info.upstream, "non-commercial", "arXiv:2306.08861"):
            assert piece in info.attribution


def test_unknown_name_suggests_close_match():
    with pytest.raises(DataError, match=r"'bandai-namco1'.*did you mean 'bandai-namco-1'"):
        get_dataset("bandai-namco1")
