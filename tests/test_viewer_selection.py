"""The viewer opens only the job folders it lists, whatever a tab sends, and keeps a bounded number
of models (#38 item 8). No browser or trained model is needed: restoring is replaced by a
recorder."""

from __future__ import annotations

import threading
from pathlib import Path
from types import SimpleNamespace

import pytest

from olatbench.viewer import server
from olatbench.viewer.server import ClientSession, ViewerApp


@pytest.fixture()
def opened(monkeypatch) -> list[Path]:
    """Every folder `ViewerModel.open` is asked to restore (it returns a stand-in model naming the
    folder)."""
    calls: list[Path] = []

    def fake_open(folder, device="cpu"):
        calls.append(Path(folder))
        return SimpleNamespace(folder=Path(folder))

    monkeypatch.setattr(server.ViewerModel, "open", staticmethod(fake_open))
    return calls


def make_app(tmp_path: Path, count: int = 3, **kwargs) -> ViewerApp:
    folders = [tmp_path / f"job{index}" for index in range(count)]
    return ViewerApp(folders, SimpleNamespace(folder=folders[0]), **kwargs)


def tab_choosing(app: ViewerApp, value: str) -> SimpleNamespace:
    """A tab's session whose job menu holds ``value`` (what the browser sent); returns what it
    showed."""
    session = object.__new__(ClientSession)
    shown = SimpleNamespace(models=[])
    session.app, session._lock = app, threading.RLock()
    session.job_dropdown = SimpleNamespace(value=value)
    session.status = SimpleNamespace(content="")
    session.use_model = shown.models.append
    session._job_chosen(SimpleNamespace(client=object()))
    shown.status = session.status.content
    return shown


@pytest.mark.parametrize("sent", ["/etc", "../job1", "{tmp}/job1/../job2", "{tmp}/elsewhere", ""])
def test_a_tab_cannot_make_the_viewer_open_an_unlisted_path(tmp_path, opened, sent):
    app = make_app(tmp_path)
    shown = tab_choosing(app, sent.replace("{tmp}", str(tmp_path)))
    assert opened == [] and shown.models == []
    assert "cannot show the chosen job" in shown.status and "not one of the jobs" in shown.status
    with pytest.raises(ValueError, match="not one of the jobs this viewer serves"):
        app.model(Path(sent.replace("{tmp}", str(tmp_path))))
    assert opened == []


def test_a_listed_job_is_restored_once_and_shown(tmp_path, opened):
    app = make_app(tmp_path)
    shown = tab_choosing(app, str(tmp_path / "job2"))
    assert opened == [tmp_path / "job2"] and [m.folder for m in shown.models] == [tmp_path / "job2"]
    tab_choosing(app, str(tmp_path / "job2"))
    assert opened == [tmp_path / "job2"]  # kept


def test_the_model_cache_keeps_the_most_recently_used_models_only(tmp_path, opened):
    app = make_app(tmp_path, count=5, max_models=2)
    for index in (1, 2, 3):
        app.model(tmp_path / f"job{index}")
    assert len(app._models) == 2 and list(app._models) == [tmp_path / "job2", tmp_path / "job3"]
    app.model(tmp_path / "job2")  # used again: now the most recent
    app.model(tmp_path / "job4")
    assert list(app._models) == [tmp_path / "job2", tmp_path / "job4"]
    app.model(tmp_path / "job0")  # evicted earlier: restored again
    assert opened == [tmp_path / f"job{index}" for index in (1, 2, 3, 4, 0)]
