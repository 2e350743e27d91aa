"""The run session as a library call (olatbench.bench.session): what `olatbench run` does after
planning, from a notebook, with the command line's decisions and exit codes."""

from __future__ import annotations

from pathlib import Path

import pytest
import test_runner_support as support

from olatbench.atomic import WriteError
from olatbench.bench import session
from olatbench.bench.plan import make_plan
from olatbench.bench.results import read_results
from olatbench.bench.store import job_state


@pytest.fixture()
def data(tmp_path):
    return support.write_tiny_data(tmp_path / "data")


def plan(data, out, **kwargs):
    return make_plan("trivial", support.tiny_suite(), out, data_root=data, progress=False, **kwargs)


def test_run_plan_runs_every_job_then_skips_them(data, tmp_path):
    out = tmp_path / "runs"
    seen = []
    summary = session.run_plan(plan(data, out), out, progress=False, on_outcome=seen.append)
    assert summary.exit_code == session.EXIT_DONE and summary.failed == 0 and summary.elsewhere == 0
    assert (
        [outcome.status for outcome in summary.outcomes]
        == ["done", "done"]
        == [o.status for o in seen]
    )
    folders = [Path(job.folder) for job in plan(data, out)]
    first = read_results(folders[0] / "results.json")
    again = session.run_plan(plan(data, out), out, progress=False)
    # finished jobs are skipped
    assert again.outcomes == [] and again.exit_code == session.EXIT_DONE
    assert read_results(folders[0] / "results.json") == first


def test_a_failed_job_and_a_job_left_to_another_process_give_the_documented_codes(data, tmp_path):
    from olatbench.bench.outcome import JobOutcome

    done = JobOutcome("a", "a", "f", "done")
    failed = JobOutcome("b", "b", "f", "failed", error="boom")
    locked = JobOutcome("c", "c", "f", "skipped", error="running in another process")
    assert session.RunSummary([done], running=0).exit_code == 0
    assert session.RunSummary([done, locked], running=0).exit_code == 3
    assert session.RunSummary([done], running=1).exit_code == 3
    # a failure outranks the rest
    assert session.RunSummary([failed, locked], running=1).exit_code == 1


def test_triage_refuses_stale_folders_unless_told_and_keeps_finished_ones(data, tmp_path):
    out = tmp_path / "runs"
    session.run_plan(plan(data, out, seeds=2), out, progress=False)
    changed = plan(data, out, seeds=2, overrides={"lr": 0.5})  # another variant name: other folders
    assert all(job_state(job.folder, job.id).state == "absent" for job in changed)
    moved = [
        type(job)(**{**job.__dict__, "folder": original.folder})
        for job, original in zip(changed, plan(data, out, seeds=2), strict=True)
    ]
    states = session.job_states(moved)
    assert {state.state for state in states} == {"stale"}
    with pytest.raises(session.StaleFoldersError, match="--keep-finished"):
        session.triage(moved, states)
    kept = session.triage(moved, states, keep_finished=True)
    assert [job.folder for job in kept.kept] == [job.folder for job in moved] and kept.to_run == []
    forced = session.triage(moved, states, force=True)
    assert forced.to_run == moved and forced.replaced == {job.folder for job in moved}


def test_prepare_names_an_unwritable_output_before_touching_anything(data, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    jobs = plan(data, blocker / "runs")
    decided = session.triage(jobs, session.job_states(jobs))
    with pytest.raises((WriteError, OSError)):
        session.prepare(decided)
    assert blocker.read_text() == "not a folder"


def test_an_unknown_executor_is_refused():
    with pytest.raises(ValueError, match="unknown executor 'pbs'"):
        session.Executor("pbs")
