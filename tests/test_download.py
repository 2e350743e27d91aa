"""`olatbench datasets download`/`verify` against a local HTTP server on 127.0.0.1 standing in for
the official hosts (a Hugging Face-like tree API, the NRHints project's plain URLs): exact and
pattern-matched files, a two-part archive, fallback between sources, a path-escaping member, a
dropped connection, a corrupted byte. Nothing here touches the network."""

from __future__ import annotations

import hashlib
import io
import json
import shutil
import tarfile
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree, write_sssgs_tree
from http_fixture import LocalServer, ServerState

from olatbench.cli import main
from olatbench.datasets import load_scene
from olatbench.datasets.download import archives, fetch, manifest, transfer
from olatbench.datasets.download.sources import (
    GS3_REPO,
    GS3_REVISION,
    NRHINTS_BASE_URL,
    SOURCES,
    SSDGS_DATASET_URL,
    SSSGS_REPO,
    SSSGS_REVISION,
    sources_for,
)

# the full id the stand-in Hub knows
SSSGS_COMMIT = SSSGS_REVISION + "0" * (40 - len(SSSGS_REVISION))


def _zip_folder(folder: Path, arcname: str) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                bundle.write(path, f"{arcname}/{path.relative_to(folder)}")
    return buffer.getvalue()


def _tar_folder(folder: Path, arcname: str) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as bundle:
        bundle.add(folder, arcname=arcname)
    return buffer.getvalue()


@pytest.fixture(scope="module")
def nrhints_tree(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("nrhints") / "scene"
    write_nrhints_tree(folder, n_train=3, n_test=1)
    return folder


@pytest.fixture()
def scene_zip(nrhints_tree) -> bytes:
    """A small NRHints scene zipped under the GS³ repack's folder name of CatSmall."""
    return _zip_folder(nrhints_tree, "Cat_on_Decor")


def _hub_state(
    files: dict[str, bytes],
    *,
    repo: str = GS3_REPO,
    revision: str = GS3_REVISION,
    with_hashes: bool = True,
    state: ServerState | None = None,
) -> ServerState:
    """A Hub stand-in: ``files`` (repository path -> bytes) under resolve/, listed by the tree
    API."""
    state = state or ServerState()
    listing = []
    for name, data in files.items():
        state.files[f"/datasets/{repo}/resolve/{revision}/{name}"] = data
        entry = {"type": "file", "path": name, "size": len(data)}
        if with_hashes:
            entry["lfs"] = {"oid": hashlib.sha256(data).hexdigest(), "size": len(data)}
        listing.append(entry)
    listing.append({"type": "file", "path": "README.md", "size": 3})
    state.listings[f"/api/datasets/{repo}/tree/{revision}"] = listing
    return state


def _sssgs_hub(files: dict[str, bytes], state: ServerState | None = None) -> ServerState:
    """The SSS-GS stand-in: files at the full commit of the pinned revision, found in main's commit
    listing."""
    state = _hub_state(files, repo=SSSGS_REPO, revision=SSSGS_COMMIT, state=state)
    later = [{"id": f"{index:040x}", "title": "README"} for index in range(1, 4)]
    state.listings[f"/api/datasets/{SSSGS_REPO}/commits/main"] = [
        *later,
        {"id": SSSGS_COMMIT, "title": "card"},
    ]
    return state


def test_hub_source_fetches_the_exact_file_validates_and_normalises_the_alias(
    tmp_path, scene_zip, nrhints_tree
):
    other = _zip_folder(nrhints_tree, "Cat")
    state = _hub_state({"NRHints/Cat_on_Decor.zip": scene_zip, "NRHints/Cat.zip": other})
    with LocalServer(state) as server:
        folder = fetch.download_scene(
            "nrhints",
            "CatSmall",
            tmp_path / "data",
            source="gs3-hf",
            mirror=server.url,
            progress=False,
        )
        cat = fetch.download_scene(
            "nrhints", "Cat", tmp_path / "data", source="gs3-hf", mirror=server.url, progress=False
        )
    assert folder == tmp_path / "data" / "CatSmall" and cat == tmp_path / "data" / "Cat"
    assert len(load_scene(folder).split("train")) == 3
    assert manifest.verify_folder(folder) == []
    # 'Cat' shares its prefix with 'Cat_on_Decor': only the exact path is fetched for each scene
    fetched = [path.rsplit("/", 1)[-1] for path, _ in state.requests if "/resolve/" in path]
    assert sorted(fetched) == ["Cat.zip", "Cat_on_Decor.zip"]
    assert json.loads((cat / manifest.MANIFEST_NAME).read_text())["archives"] == {
        "Cat.zip": hashlib.sha256(other).hexdigest()
    }
    assert not [p for p in (tmp_path / "data").iterdir() if p.name.startswith(".unpack")]


def test_url_source_downloads_unpacks_aliases_and_validates(tmp_path, nrhints_tree):
    """The NRHints project's plain URLs, with --mirror pointing the base URL at the local server."""
    data = _zip_folder(nrhints_tree, "Cluttered")  # an archive whose folder is an alias of FurScene
    state = ServerState(files={"/FurScene.zip": data})
    runner = CliRunner()
    root = tmp_path / "data"
    with LocalServer(state) as server:
        result = runner.invoke(
            main,
            [
                "datasets",
                "download",
                "nrhints",
                "--scenes",
                "FurScene",
                "--root",
                str(root),
                "--source",
                "nrhints-project",
                "--mirror",
                server.url,
            ],
        )
    assert result.exit_code == 0, result.output
    assert [path for path, _ in state.requests] == ["/FurScene.zip"]
    assert len(load_scene(root / "FurScene").split("train")) == 3
    assert (
        json.loads((root / "FurScene" / manifest.MANIFEST_NAME).read_text())["source"]
        == "nrhints-project"
    )
    assert runner.invoke(main, ["datasets", "verify", str(root)]).exit_code == 0


def test_url_sources_default_to_the_official_locations():
    """Without --mirror the NRHints files resolve to the project's host
    (no network needed to resolve)."""
    for scene in ("Cat", "CatSmall", "Pikachu"):
        (source,) = sources_for("nrhints", scene, "nrhints-project")
        assert [f.url for f in fetch.resolve_files(source)] == [f"{NRHINTS_BASE_URL}/{scene}.zip"]


def test_nrhints_defaults_to_the_papers_copy_then_the_authors_zips():
    """SSD-GS trains on the GS³ re-pack of NRHints: it is tried first; the SSD-GS authors' copy is
    listed last."""
    for scene in SOURCES["nrhints"]:
        assert [s.name for s in sources_for("nrhints", scene)] == [
            "gs3-hf",
            "nrhints-project",
            "ssdgs-release",
        ]


def test_unusable_source_falls_back_to_the_next(tmp_path, nrhints_tree):
    """The (stand-in) Hub answers 404 for the GS³ re-pack, so the NRHints project's zip is used
    instead."""
    state = ServerState(files={"/CatSmall.zip": _zip_folder(nrhints_tree, "CatSmall")})
    with LocalServer(state) as server:
        folder = fetch.download_scene(
            "nrhints", "CatSmall", tmp_path, mirror=server.url, progress=False
        )
    assert json.loads((folder / manifest.MANIFEST_NAME).read_text())["source"] == "nrhints-project"
    assert state.requests[0] == (f"/api/datasets/{GS3_REPO}/tree/{GS3_REVISION}", None)
    assert state.requests[-1] == ("/CatSmall.zip", None)


def test_missing_hub_file_names_what_the_repository_holds(tmp_path):
    state = _hub_state({"Synthetic/Lego_v2.zip": b"x"})
    with LocalServer(state) as server, pytest.raises(transfer.DownloadError) as error:
        fetch.download_scene("gs3", "Lego", tmp_path, mirror=server.url, progress=False)
    assert "Synthetic/Lego.zip not found" in str(error.value) and "Synthetic/Lego_v2.zip" in str(
        error.value
    )


def test_pattern_matched_two_part_archive_is_joined_and_aliased(tmp_path):
    """SSS-GS archives are matched by pattern (exact names unpublished); numbered parts are joined
    in order."""
    write_sssgs_tree(tmp_path / "src")
    data = _tar_folder(tmp_path / "src", "bunny_small")
    half = len(data) // 2
    parts = {
        "synthetic/bunny_small.tar.002": data[half:],
        "synthetic/bunny_small.tar.001": data[:half],
        "synthetic/bunny_small/transforms_train.json": b"{}",
        "real_world/bunny.tar": b"x",
    }
    state = _sssgs_hub(parts)
    with LocalServer(state) as server:
        folder = fetch.download_scene(
            "sssgs",
            "Bunny",
            tmp_path / "data",
            source="sssgs-hf",
            mirror=server.url,
            progress=False,
        )
    assert folder == tmp_path / "data" / "Bunny"
    assert len(load_scene(folder).split("test")) == 3
    assert sorted(json.loads((folder / manifest.MANIFEST_NAME).read_text())["archives"]) == [
        "bunny_small.tar.001",
        "bunny_small.tar.002",
    ]


def test_several_matching_archives_are_refused(tmp_path):
    state = _sssgs_hub({"synthetic/bunny_small.tar": b"a", "synthetic/bunny_small_hdr.zip": b"b"})
    (source,) = sources_for("sssgs", "Bunny", "sssgs-hf")
    with (
        LocalServer(state) as server,
        pytest.raises(transfer.DownloadError, match="several archives match"),
    ):
        fetch.resolve_files(source, server.url)


def test_dropped_connection_resumes_with_a_range_request(tmp_path, scene_zip):
    state = _hub_state({"NRHints/Cat_on_Decor.zip": scene_zip})
    path = f"/datasets/{GS3_REPO}/resolve/{GS3_REVISION}/NRHints/Cat_on_Decor.zip"
    state.drop_after[path] = len(scene_zip) // 3
    with LocalServer(state) as server:
        fetch.download_scene(
            "nrhints", "CatSmall", tmp_path, source="gs3-hf", mirror=server.url, progress=False
        )
    ranges = [rng for p, rng in state.requests if p == path]
    assert ranges[0] is None and ranges[1] == f"bytes={len(scene_zip) // 3}-"


def test_corrupted_byte_stops_with_both_hashes_and_installs_nothing(tmp_path, scene_zip):
    state = _hub_state({"NRHints/Cat_on_Decor.zip": scene_zip})
    corrupted = bytearray(scene_zip)
    corrupted[len(corrupted) // 2] ^= 0xFF
    state.files[f"/datasets/{GS3_REPO}/resolve/{GS3_REVISION}/NRHints/Cat_on_Decor.zip"] = bytes(
        corrupted
    )
    with LocalServer(state) as server, pytest.raises(manifest.IntegrityError) as error:
        fetch.download_scene("nrhints", "CatSmall", tmp_path, mirror=server.url, progress=False)
    message = str(error.value)
    assert "Cat_on_Decor.zip" in message
    assert hashlib.sha256(scene_zip).hexdigest() in message
    assert hashlib.sha256(bytes(corrupted)).hexdigest() in message
    assert not (tmp_path / "CatSmall").exists()


def test_mirror_hash_recorded_first_time_and_checked_later(tmp_path, nrhints_tree):
    data = _zip_folder(nrhints_tree, "CatSmall")
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "CatSmall.zip").write_bytes(data)
    root = tmp_path / "data"
    fetch.download_scene(
        "nrhints",
        "CatSmall",
        root,
        source="nrhints-project",
        mirror=mirror.as_uri(),
        progress=False,
    )
    recorded = json.loads((root / fetch.KNOWN_HASHES).read_text())
    assert recorded == {"nrhints-project/CatSmall.zip": hashlib.sha256(data).hexdigest()}
    # the mirror changes under us: the next fresh download refuses it
    (mirror / "CatSmall.zip").write_bytes(data[:-1] + bytes([data[-1] ^ 1]))
    shutil.rmtree(root / "CatSmall")
    shutil.rmtree(root / fetch.DOWNLOADS)
    with pytest.raises(manifest.IntegrityError):
        fetch.download_scene(
            "nrhints",
            "CatSmall",
            root,
            source="nrhints-project",
            mirror=mirror.as_uri(),
            progress=False,
        )


def test_path_escaping_members_are_refused_before_writing(tmp_path):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        bundle.writestr("scene/ok.txt", "fine")
        bundle.writestr("../evil.txt", "escape")
    archive = tmp_path / "bad.zip"
    archive.write_bytes(buffer.getvalue())
    with pytest.raises(archives.UnsafeArchiveError, match=r"\.\./evil\.txt"):
        archives.extract(archive, tmp_path / "out")
    assert (
        not (tmp_path / "evil.txt").exists()
        and not (tmp_path / "out" / "scene" / "ok.txt").exists()
    )


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
    with (
        LocalServer(ServerState()) as server,
        pytest.raises(transfer.DownloadError, match="HTTP 404"),
    ):
        transfer.download(
            f"{server.url}/missing.zip", tmp_path / "missing.zip", retries=1, backoff=0
        )


def test_unreachable_hub_then_manual_sources_fail_cleanly_with_instructions(tmp_path, monkeypatch):
    """SSS-GS: the Hub (a local stand-in answering 404) fails, the mirror-only source prints how to
    use it."""
    with LocalServer(ServerState()) as server:
        # the Hub's own variable points olatbench at the stand-in
        monkeypatch.setenv("HF_ENDPOINT", server.url)
        result = CliRunner().invoke(
            main, ["datasets", "download", "sssgs", "--scenes", "Bunny", "--root", str(tmp_path)]
        )
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert "[sssgs-hf]" in result.output and "404" in result.output and server.url in result.output
    assert "--mirror" in result.output and "[ssdgs-release]" in result.output
    # the Hub failure was a download error
    assert "rerun the same command to resume" in result.output


def test_manual_only_sources_say_so_instead_of_suggesting_a_rerun(tmp_path):
    result = CliRunner().invoke(
        main,
        [
            "datasets",
            "download",
            "sssgs",
            "--scenes",
            "Bunny",
            "--root",
            str(tmp_path),
            "--source",
            "ssdgs-release",
        ],
    )
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert (
        "NEEDS A MANUAL STEP" in result.output and "follow the instructions above" in result.output
    )
    assert SSDGS_DATASET_URL in result.output.replace("\n", "").replace(" ", "")
    assert "Synthetic_SSS-GS" in result.output
    assert "resume" not in result.output


def test_verify_reports_a_damaged_file(tmp_path, nrhints_tree):
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "CatSmall.zip").write_bytes(_zip_folder(nrhints_tree, "CatSmall"))
    root = tmp_path / "data"
    runner = CliRunner()
    result = runner.invoke(
        main,
        [
            "datasets",
            "download",
            "nrhints",
            "--scenes",
            "CatSmall",
            "--root",
            str(root),
            "--source",
            "nrhints-project",
            "--mirror",
            mirror.as_uri(),
        ],
    )
    assert result.exit_code == 0, result.output
    assert runner.invoke(main, ["datasets", "verify", str(root)]).exit_code == 0
    victim = next((root / "CatSmall").rglob("*.png"))
    victim.write_bytes(victim.read_bytes()[:-3])
    result = runner.invoke(main, ["datasets", "verify", str(root)])
    assert result.exit_code != 0 and victim.name in result.output and "DAMAGED" in result.output


def test_ssdgs_release_is_offered_for_every_suite_with_its_folder():
    for suite, folder in (
        ("nrhints", "Real_NRHints"),
        ("gs3", "Synthetic_GS3"),
        ("sssgs", "Synthetic_SSS-GS"),
    ):
        for scene in SOURCES[suite]:
            (source,) = sources_for(suite, scene, "ssdgs-release")
            assert source.kind == "manual" and SSDGS_DATASET_URL in source.instructions
            assert f"--data-root /path/to/data/{folder}" in source.instructions


def test_hub_listings_are_followed_page_by_page_and_the_revision_is_resolved(tmp_path):
    """The Hub pages its tree and commit listings (Link: rel="next"); the archive is on the last
    tree page and the pinned commit on the last commit page, so a reader of the first page only
    would find neither."""
    write_sssgs_tree(tmp_path / "src")
    data = _tar_folder(tmp_path / "src", "bunny_small")
    files = {f"synthetic/other_{index}.json": b"{}" for index in range(5)}
    files["synthetic/bunny_small.tar"] = data
    state = _sssgs_hub(files)
    state.page_size = 2
    (source,) = sources_for("sssgs", "Bunny", "sssgs-hf")
    with LocalServer(state) as server:
        (remote,) = fetch.resolve_files(source, server.url)
    assert (
        remote.url
        == f"{server.url}/datasets/{SSSGS_REPO}/resolve/{SSSGS_COMMIT}/synthetic/bunny_small.tar"
    )
    assert remote.sha256 == hashlib.sha256(data).hexdigest()
    pages = [path for path, _ in state.requests]
    assert pages.count(f"/api/datasets/{SSSGS_REPO}/commits/main") == 2
    # 7 entries, 2 per page
    assert pages.count(f"/api/datasets/{SSSGS_REPO}/tree/{SSSGS_COMMIT}") == 4


def test_a_pinned_revision_missing_from_the_history_stops(tmp_path):
    state = _sssgs_hub({"synthetic/bunny_small.tar": b"a"})
    state.listings[f"/api/datasets/{SSSGS_REPO}/commits/main"] = [{"id": "f" * 40}]
    (source,) = sources_for("sssgs", "Bunny", "sssgs-hf")
    with (
        LocalServer(state) as server,
        pytest.raises(transfer.DownloadError, match=f"revision {SSSGS_REVISION}"),
    ):
        fetch.resolve_files(source, server.url)


def test_hf_token_is_sent_to_the_hub_only(tmp_path, monkeypatch, scene_zip):
    """$HF_TOKEN goes to every Hub request (listing and download) as a Bearer token; never to a URL
    source."""
    monkeypatch.setenv("HF_TOKEN", "hf_test_token")
    state = _hub_state({"NRHints/Cat_on_Decor.zip": scene_zip})
    with LocalServer(state) as server:
        fetch.download_scene(
            "nrhints",
            "CatSmall",
            tmp_path / "hub",
            source="gs3-hf",
            mirror=server.url,
            progress=False,
        )
    assert state.authorization and all(
        value == "Bearer hf_test_token" for _, value in state.authorization
    )
    plain = ServerState(files={"/CatSmall.zip": scene_zip})
    with LocalServer(plain) as server:
        fetch.download_scene(
            "nrhints",
            "CatSmall",
            tmp_path / "url",
            source="nrhints-project",
            mirror=server.url,
            progress=False,
        )
    assert plain.authorization == [("/CatSmall.zip", None)]
    monkeypatch.delenv("HF_TOKEN")
    assert fetch.hub_headers() == {}


def test_hub_endpoint_order(monkeypatch):
    monkeypatch.delenv("HF_ENDPOINT", raising=False)
    assert fetch.hub_endpoint() == "https://huggingface.co"
    monkeypatch.setenv("HF_ENDPOINT", "https://hf-mirror.example/")
    assert fetch.hub_endpoint() == "https://hf-mirror.example"
    assert fetch.hub_endpoint("http://127.0.0.1:9") == "http://127.0.0.1:9"  # --mirror wins


def test_link_header_parsing():
    assert (
        transfer.next_link('<https://huggingface.co/api/x?cursor=abc>; rel="next"')
        == "https://huggingface.co/api/x?cursor=abc"
    )
    assert (
        transfer.next_link('<https://a/prev>; rel="prev", <https://a/next>; rel="next"')
        == "https://a/next"
    )
    assert (
        transfer.next_link(None) is None and transfer.next_link('<https://a/p>; rel="prev"') is None
    )


# --- #38: nothing deleted that olatbench did not write; damaged archives never poison the cache


def _mirror(tmp_path: Path, name: str, data: bytes) -> Path:
    mirror = tmp_path / "mirror"
    mirror.mkdir(exist_ok=True)
    (mirror / name).write_bytes(data)
    return mirror


def _download(root: Path, mirror: Path, scene: str = "CatSmall"):
    return CliRunner().invoke(
        main,
        [
            "datasets",
            "download",
            "nrhints",
            "--scenes",
            scene,
            "--data-root",
            str(root),
            "--source",
            "nrhints-project",
            "--mirror",
            mirror.as_uri(),
        ],
    )


def test_a_scene_folder_olatbench_did_not_write_is_left_untouched(tmp_path, nrhints_tree):
    """#38 item 1: ROOT/Cat without olatbench's manifest was removed with shutil.rmtree; now it
    stays, and the error gives the command that replaces it."""
    mirror = _mirror(tmp_path, "Cat.zip", _zip_folder(nrhints_tree, "Cat"))
    root = tmp_path / "data"
    (root / "Cat").mkdir(parents=True)
    (root / "Cat" / "NOTES.txt").write_text("mine")
    result = _download(root, mirror, "Cat")
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert (root / "Cat" / "NOTES.txt").read_text() == "mine" and sorted(
        p.name for p in root.iterdir()
    ) == ["Cat"]
    assert "was not downloaded by olatbench" in result.output and "left untouched" in result.output
    assert (
        f"mv {root / 'Cat'} {root / 'Cat'}.mine && olatbench datasets download nrhints --scenes Cat"
        in result.output
    )
    # the command it prints does replace it
    (root / "Cat").rename(root / "Cat.mine")
    assert (
        _download(root, mirror, "Cat").exit_code == 0 and manifest.verify_folder(root / "Cat") == []
    )


def test_a_downloaded_scene_edited_afterwards_is_moved_aside_not_deleted(tmp_path, nrhints_tree):
    """#38 item 1: a folder that differs from its manifest is renamed beside the new copy, and the
    output says where; every file of it survives."""
    mirror = _mirror(tmp_path, "CatSmall.zip", _zip_folder(nrhints_tree, "CatSmall"))
    root = tmp_path / "data"
    assert _download(root, mirror).exit_code == 0
    (root / "CatSmall" / "NOTES.txt").write_text("mine")
    edited = next((root / "CatSmall").rglob("*.png"))
    edited.write_bytes(b"my retouched image")
    result = _download(root, mirror)
    assert result.exit_code == 0, result.output
    (aside,) = root.glob("CatSmall.replaced-*")
    assert (aside / "NOTES.txt").read_text() == "mine"
    assert (aside / edited.relative_to(root / "CatSmall")).read_bytes() == b"my retouched image"
    assert str(aside) in result.output and "nothing in it was deleted" in result.output
    assert manifest.verify_folder(root / "CatSmall") == []


def test_a_truncated_archive_does_not_poison_the_cache(tmp_path, nrhints_tree):
    """#38 item 2: a truncated mirror file recorded its hash before unpacking and stayed cached, so
    every rerun repeated a tarfile traceback and the repaired archive was then refused as a sha256
    mismatch."""
    good = _tar_folder(nrhints_tree, "CatSmall")
    # the source's name; tar content
    mirror = _mirror(tmp_path, "CatSmall.zip", good[: len(good) // 2])
    root = tmp_path / "data"
    result = _download(root, mirror)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "CatSmall.zip: damaged or truncated archive" in result.output, result.output
    assert not (root / fetch.KNOWN_HASHES).exists()  # a damaged download is never the reference
    cache = root / fetch.DOWNLOADS / "nrhints-project"
    assert sorted(p.name for p in cache.iterdir()) == ["CatSmall.zip.damaged"]
    assert "rerun to download it again" in result.output
    (mirror / "CatSmall.zip").write_bytes(good)  # the mirror is repaired: a plain rerun works
    result = _download(root, mirror)
    assert result.exit_code == 0, result.output
    assert json.loads((root / fetch.KNOWN_HASHES).read_text()) == {
        "nrhints-project/CatSmall.zip": hashlib.sha256(good).hexdigest()
    }


def test_a_recorded_hash_mismatch_says_how_to_accept_a_changed_source(tmp_path, nrhints_tree):
    """#38 item 2: "rerun" alone looped; a mismatch with a recorded hash names the entry to
    delete."""
    data = _zip_folder(nrhints_tree, "CatSmall")
    mirror = _mirror(tmp_path, "CatSmall.zip", data)
    root = tmp_path / "data"
    assert _download(root, mirror).exit_code == 0
    shutil.rmtree(root / fetch.DOWNLOADS)
    (mirror / "CatSmall.zip").write_bytes(_zip_folder(nrhints_tree, "Cat_on_Decor"))
    (root / "CatSmall" / manifest.MANIFEST_NAME).unlink()
    shutil.move(root / "CatSmall", tmp_path / "elsewhere")
    result = _download(root, mirror)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert (
        "entry 'nrhints-project/CatSmall.zip'" in result.output
        and "delete that entry and rerun" in result.output
    )


def _tgz(members: dict[str, bytes], mode: str = "w:gz") -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as bundle:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            bundle.addfile(info, io.BytesIO(data))
    return buffer.getvalue()


def test_an_unreadable_record_of_hashes_is_one_error(tmp_path, nrhints_tree):
    mirror = _mirror(tmp_path, "CatSmall.zip", _zip_folder(nrhints_tree, "CatSmall"))
    root = tmp_path / "data"
    root.mkdir()
    (root / fetch.KNOWN_HASHES).write_text("{truncated")
    result = _download(root, mirror)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert (
        fetch.KNOWN_HASHES in result.output
        and "unreadable record of archive hashes" in result.output
    )


def test_a_decompression_bomb_is_refused_while_unpacking(tmp_path):
    """#38 item 3: 96 MiB of zeros in a ~100 kB tar.gz goes over the limit (20 × the archive, at
    least 64 MiB)."""
    archive = tmp_path / "bomb.tar.gz"
    archive.write_bytes(_tgz({"scene/zeros.bin": bytes(96 << 20)}))
    assert archive.stat().st_size < 1 << 20
    with pytest.raises(archives.UnsafeArchiveError, match="decompression bomb"):
        archives.extract(archive, tmp_path / "out")
    assert (
        sum(p.stat().st_size for p in (tmp_path / "out").rglob("*") if p.is_file())
        <= archives.UNPACK_FLOOR
    )


def test_a_tar_member_named_dot_is_refused(tmp_path):
    """#38 item 3: a file member '.' crashed with IsADirectoryError."""
    archive = tmp_path / "dot.tar"
    archive.write_bytes(_tgz({".": b"x"}, mode="w"))
    with pytest.raises(archives.UnsafeArchiveError, match="without a file name"):
        archives.extract(archive, tmp_path / "out")


def test_an_archive_that_is_no_scene_leaves_the_cache_too(tmp_path, nrhints_tree):
    """A mirror serving the wrong file: the readable archive that holds no scene does not stay
    cached to fail again; a rerun after the mirror is fixed installs the scene."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        bundle.writestr("CatSmall/README.txt", "the scene is elsewhere")
    mirror = _mirror(tmp_path, "CatSmall.zip", buffer.getvalue())
    root = tmp_path / "data"
    result = _download(root, mirror)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "is not a valid scene" in result.output and "CatSmall.zip.damaged" in result.output
    (mirror / "CatSmall.zip").write_bytes(_zip_folder(nrhints_tree, "CatSmall"))
    assert _download(root, mirror).exit_code == 0
