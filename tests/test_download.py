"""`olatbench datasets download`/`verify` against a local HTTP server on 127.0.0.1 serving archives
built from small generated scenes (a Hugging Face-like tree API, a two-part archive, a path-escaping
member, a dropped connection, a corrupted byte)."""

from __future__ import annotations

import hashlib
import io
import json
import tarfile
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree
from http_fixture import LocalServer, ServerState

from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.datasets.download import archives, fetch, manifest, transfer
from olatbench.datasets.download.sources import GS3_REPO


def _zip_folder(folder: Path, arcname: str) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                bundle.write(path, f"{arcname}/{path.relative_to(folder)}")
    return buffer.getvalue()


@pytest.fixture()
def scene_zip(tmp_path) -> bytes:
    """A small NRHints scene zipped under the alias folder name of CatSmall."""
    write_nrhints_tree(tmp_path / "src", n_train=3, n_test=1)
    return _zip_folder(tmp_path / "src", "Cat_on_Decor")


def _hf_state(files: dict[str, bytes], *, with_hashes: bool = True) -> ServerState:
    state = ServerState()
    listing = []
    for name, data in files.items():
        state.files[f"/datasets/{GS3_REPO}/resolve/main/{name}"] = data
        entry = {"type": "file", "path": name, "size": len(data)}
        if with_hashes:
            entry["lfs"] = {"oid": hashlib.sha256(data).hexdigest(), "size": len(data)}
        listing.append(entry)
    listing.append({"type": "file", "path": "README.md", "size": 3})
    state.listings[f"/api/datasets/{GS3_REPO}/tree/main"] = listing
    return state


def test_hub_source_downloads_validates_and_normalises_the_alias(tmp_path, scene_zip):
    state = _hf_state({"nrhints/Cat_on_Decor.zip": scene_zip})
    with LocalServer(state) as server:
        folder = fetch.download_scene("nrhints", "CatSmall", tmp_path / "data", source="gs3-hf",
                                      mirror=server.url, progress=False)
    assert folder == tmp_path / "data" / "CatSmall"
    assert len(load_scene(folder).split("train")) == 3
    assert manifest.verify_folder(folder) == []
    assert not [p for p in (tmp_path / "data").iterdir() if p.name.startswith(".unpack")]


def test_dropped_connection_resumes_with_a_range_request(tmp_path, scene_zip):
    state = _hf_state({"Cat_on_Decor.zip": scene_zip})
    path = f"/datasets/{GS3_REPO}/resolve/main/Cat_on_Decor.zip"
    state.drop_after[path] = len(scene_zip) // 3
    with LocalServer(state) as server:
        fetch.download_scene("nrhints", "CatSmall", tmp_path, source="gs3-hf", mirror=server.url, progress=False)
    ranges = [rng for p, rng in state.requests if p == path]
    assert ranges[0] is None and ranges[1] == f"bytes={len(scene_zip) // 3}-"


def test_corrupted_byte_stops_with_both_hashes_and_installs_nothing(tmp_path, scene_zip):
    state = _hf_state({"Cat_on_Decor.zip": scene_zip})
    corrupted = bytearray(scene_zip)
    corrupted[len(corrupted) // 2] ^= 0xFF
    state.files[f"/datasets/{GS3_REPO}/resolve/main/Cat_on_Decor.zip"] = bytes(corrupted)
    with LocalServer(state) as server, pytest.raises(manifest.IntegrityError) as error:
        fetch.download_scene("nrhints", "CatSmall", tmp_path, source="gs3-hf", mirror=server.url, progress=False)
    message = str(error.value)
    assert "Cat_on_Decor.zip" in message
    assert hashlib.sha256(scene_zip).hexdigest() in message
    assert hashlib.sha256(bytes(corrupted)).hexdigest() in message
    assert not (tmp_path / "CatSmall").exists()


def test_mirror_hash_recorded_first_time_and_checked_later(tmp_path, scene_zip):
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "Cat_on_Decor.zip").write_bytes(scene_zip)
    root = tmp_path / "data"
    fetch.download_scene("nrhints", "CatSmall", root, source="nrhints-project", mirror=mirror.as_uri(),
                         progress=False)
    recorded = json.loads((root / fetch.KNOWN_HASHES).read_text())
    assert recorded["Cat_on_Decor.zip"] == hashlib.sha256(scene_zip).hexdigest()
    # the mirror changes under us: the next fresh download refuses it
    (mirror / "Cat_on_Decor.zip").write_bytes(scene_zip[:-1] + bytes([scene_zip[-1] ^ 1]))
    import shutil
    shutil.rmtree(root / "CatSmall")
    shutil.rmtree(root / fetch.DOWNLOADS)
    with pytest.raises(manifest.IntegrityError):
        fetch.download_scene("nrhints", "CatSmall", root, source="nrhints-project", mirror=mirror.as_uri(),
                             progress=False)


def test_two_part_archive_is_joined(tmp_path):
    write_nrhints_tree(tmp_path / "src", n_train=2, n_test=1)
    data = _zip_folder(tmp_path / "src", "Pikachu")
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "Pikachu.zip.001").write_bytes(data[: len(data) // 2])
    (mirror / "Pikachu.zip.002").write_bytes(data[len(data) // 2:])
    folder = fetch.download_scene("nrhints", "Pikachu", tmp_path / "data", source="nrhints-project",
                                  mirror=mirror.as_uri(), progress=False)
    assert len(load_scene(folder).split("test")) == 1


def test_path_escaping_members_are_refused_before_writing(tmp_path):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        bundle.writestr("scene/ok.txt", "fine")
        bundle.writestr("../evil.txt", "escape")
    archive = tmp_path / "bad.zip"
    archive.write_bytes(buffer.getvalue())
    with pytest.raises(archives.UnsafeArchiveError, match=r"\.\./evil\.txt"):
        archives.extract(archive, tmp_path / "out")
    assert not (tmp_path / "evil.txt").exists() and not (tmp_path / "out" / "scene" / "ok.txt").exists()


@pytest.mark.parametrize("member", ["/etc/passwd-copy", "link"])
def test_tar_absolute_paths_and_links_are_refused(tmp_path, member):
    archive = tmp_path / "bad.tar"
    with tarfile.open(archive, "w") as bundle:
        info = tarfile.TarInfo(member)
        if member == "link":
            info.type, info.linkname = tarfile.SYMTYPE, "/etc/passwd"
            bundle.addfile(info)
        else:
            info.size = 1
            bundle.addfile(info, io.BytesIO(b"x"))
    with pytest.raises(archives.UnsafeArchiveError):
        archives.extract(archive, tmp_path / "out")


def test_server_error_is_reported_with_the_url(tmp_path):
    with LocalServer(ServerState()) as server, pytest.raises(transfer.DownloadError, match="HTTP 404"):
        transfer.download(f"{server.url}/missing.zip", tmp_path / "missing.zip", retries=1, backoff=0)


def test_manual_source_prints_instructions_and_fails_cleanly(tmp_path):
    result = CliRunner().invoke(main, ["datasets", "download", "sssgs", "--scenes", "Bunny", "--root", str(tmp_path)])
    assert result.exit_code != 0
    assert "--mirror" in result.output and "Traceback" not in result.output


def test_verify_reports_a_damaged_file(tmp_path, scene_zip):
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "Cat_on_Decor.zip").write_bytes(scene_zip)
    root = tmp_path / "data"
    runner = CliRunner()
    result = runner.invoke(main, ["datasets", "download", "nrhints", "--scenes", "CatSmall", "--root", str(root),
                                  "--source", "nrhints-project", "--mirror", mirror.as_uri()])
    assert result.exit_code == 0, result.output
    assert runner.invoke(main, ["datasets", "verify", str(root)]).exit_code == 0
    victim = next((root / "CatSmall").rglob("*.png"))
    victim.write_bytes(victim.read_bytes()[:-3])
    result = runner.invoke(main, ["datasets", "verify", str(root)])
    assert result.exit_code != 0 and victim.name in result.output and "DAMAGED" in result.output
