"""The manifest of an unpacked data set and the comparison of a folder with it."""

from __future__ import annotations

import json
import os
import tarfile
from pathlib import Path

import pytest

from emotive.data.archive import scan
from emotive.data.manifest import (
    Manifest,
    Problem,
    check_folder,
    manifest_path,
    read_manifest,
    write_manifest,
)


@pytest.fixture
def made(fake) -> tuple[Manifest, Path]:
    """The synthetic archive's manifest (read from the archive) and a copy of its folder."""
    with open(fake.archive, "rb") as fh:
        members, hashes = scan(fh, fake.info.folder, "fake", "fix it")
    with tarfile.open(fake.archive) as tar:
        assert [m.name for m in tar.getmembers()] == [m.name for m in members]
    manifest = Manifest.from_members("fake-1", fake.info.archive, fake.info.sha256,
                                     fake.info.folder, members, hashes)
    return manifest, fake.folder


def kinds(problems: list[Problem]) -> list[tuple[str, str]]:
    return [(p.path, p.kind) for p in problems]


def test_manifest_lists_every_file_with_its_size_and_hash(made):
    manifest, folder = made
    on_disk = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert sorted(manifest.files) == on_disk and len(on_disk) == 3 + 2 * 18
    assert manifest.folders == {"cfg", "data"}
    record = manifest.files["cfg/content_label.txt"]
    assert record.size == (folder / "cfg" / "content_label.txt").stat().st_size
    assert check_folder(manifest, folder) == ([], sum(r.size for r in manifest.files.values()))


def test_json_round_trip_and_atomic_write(made, tmp_path):
    manifest, _ = made
    (tmp_path / "cache").mkdir()
    path = manifest_path(tmp_path / "cache" / "Fake-Motiondataset-1")
    assert path == tmp_path / "cache" / "Fake-Motiondataset-1.manifest.json"
    write_manifest(manifest, path)
    assert read_manifest(path) == manifest
    assert [p.name for p in path.parent.iterdir()] == [path.name]


@pytest.mark.parametrize("edit", ["outside", "absolute", "version", "not-json", "no-files"])
def test_unusable_manifest_reads_as_none(made, tmp_path, edit):
    manifest, _ = made
    data = json.loads(manifest.to_json())
    if edit == "outside":
        data["files"]["../../evil"] = [1, "0" * 64]
    elif edit == "absolute":
        data["folders"].append("/etc")
    elif edit == "version":
        data["version"] = 99
    elif edit == "no-files":
        del data["files"]
    path = tmp_path / "m.json"
    path.write_text("{" if edit == "not-json" else json.dumps(data))
    assert read_manifest(path) is None
    assert read_manifest(tmp_path / "absent.json") is None


def test_flipped_byte_missing_and_truncated_files_found(made):
    manifest, folder = made
    data = folder / "data"
    flipped = data / "dataset-1_walk_normal_001.bvh"
    raw = bytearray(flipped.read_bytes())
    raw[len(raw) // 2] ^= 0x01
    flipped.write_bytes(raw)
    (data / "dataset-1_bow_sad_002.json").unlink()
    truncated = data / "dataset-1_walk-left_happy_001.bvh"
    size = truncated.stat().st_size
    os.truncate(truncated, size - 1)
    problems, _ = check_folder(manifest, folder)
    assert kinds(problems) == [
        ("data/dataset-1_bow_sad_002.json", "missing"),
        ("data/dataset-1_walk-left_happy_001.bvh", "damaged"),
        ("data/dataset-1_walk_normal_001.bvh", "damaged"),
    ]
    assert problems[1].detail == f"{size - 1} bytes, the archive's has {size}"
    assert "sha256" in problems[2].detail


def test_extra_files_folders_and_things_in_the_way(made):
    manifest, folder = made
    (folder / "data" / "stray.bvh").write_text("x")
    (folder / "notes" / "deep").mkdir(parents=True)
    (folder / "notes" / "deep" / "a.txt").write_text("x")
    (folder / "LICENSE").unlink()
    (folder / "LICENSE").mkdir()
    (folder / "LICENSE" / "inside").write_text("x")
    (folder / "cfg" / "style_label.txt").unlink()
    (folder / "cfg" / "style_label.txt").symlink_to(folder / "cfg" / "content_label.txt")
    (folder / "marker").write_text("ours")
    problems, _ = check_folder(manifest, folder, ignore=("marker",))
    assert kinds(problems) == [
        ("LICENSE", "damaged"), ("cfg/style_label.txt", "damaged"),
        ("data/stray.bvh", "extra"), ("notes", "extra"),
    ]
    assert problems[0].detail == "is a folder, not the archive's file"
    assert problems[1].detail == "is a link or special file, not the archive's file"


def test_folder_replaced_or_gone(made):
    manifest, folder = made
    for path in (folder / "cfg").iterdir():
        path.unlink()
    (folder / "cfg").rmdir()
    (folder / "cfg").write_text("x")
    problems, _ = check_folder(manifest, folder)
    assert kinds(problems) == [
        ("cfg", "damaged"), ("cfg/content_label.txt", "missing"),
        ("cfg/style_label.txt", "missing"),
    ]
    assert check_folder(manifest, folder.parent / "nowhere")[0] == [
        Problem(".", "missing", f"the data set folder {folder.parent / 'nowhere'} is not there")
    ]
