"""Names typed on the command line (`olatbench.names`): case does not matter where one name matches,
and a miss offers the close names ("did you mean") for methods, suites, scenes, variants and
ablation grids."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from olatbench.cli import main
from olatbench.names import close_names, did_you_mean, match_name


@pytest.fixture(autouse=True)
def _isolated(tmp_path, monkeypatch):
    """Dry runs of the mini suite look for its data in the cache: a fresh one, never the user's."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)


def dry_run(*args: str):
    return CliRunner().invoke(main, ["run", *args, "--dry-run", "--json", "-o", "runs"])


def test_match_name_ignores_case_only_when_one_name_matches():
    assert match_name("ssdgs", ["3dgs", "ssdgs"]) == "ssdgs"
    assert match_name("SSDGS", ["3dgs", "ssdgs"]) == "ssdgs"
    assert match_name("lego", ["Lego", "LEGO"]) is None  # ambiguous: no guess
    assert match_name("Lego", ["Lego", "LEGO"]) == "Lego"  # exact wins
    assert match_name("ssgds", ["ssdgs"]) is None


def test_did_you_mean_offers_close_names_best_first():
    assert (
        did_you_mean("ssgds", ["3dgs", "gs3", "ssdgs", "ssdgs-official"])
        == " (did you mean 'ssdgs'?)"
    )
    assert close_names("MNII", ["nrhints", "gs3", "sssgs", "mini"]) == ["mini"]
    assert did_you_mean("zzzz", ["mini"]) == ""
    assert did_you_mean("abce", ["abcd", "abcf", "xyz"]) in (
        " (did you mean 'abcd' or 'abcf'?)",
        " (did you mean 'abcf' or 'abcd'?)",
    )


def test_a_mistyped_method_exits_2_and_suggests_the_close_one():
    result = dry_run("-m", "ssgds", "-s", "mini")
    assert result.exit_code == 2
    assert "unknown method 'ssgds' (did you mean 'ssdgs'?)" in result.output
    assert "Traceback" not in result.output


def test_method_and_suite_names_ignore_case():
    upper = dry_run("-m", "SSDGS", "-s", "MINI", "--scenes", "Translucent")
    assert upper.exit_code == 0, upper.output
    jobs = json.loads(upper.output)
    assert [(job["method"], job["suite"], job["scene"]) for job in jobs] == [
        ("ssdgs", "mini", "translucent")
    ]
    assert jobs[0]["folder"].startswith("mini/ssdgs/default/translucent")
    assert jobs == json.loads(
        dry_run("-m", "ssdgs", "-s", "mini", "--scenes", "translucent").output
    )


@pytest.mark.parametrize(
    ("args", "hint"),
    [
        (("-m", "ssdgs", "-s", "mnii"), "unknown suite 'mnii' (did you mean 'mini'?)"),
        (
            ("-m", "ssdgs", "-s", "mini", "--scenes", "translucnet"),
            "no scene 'translucnet' (did you mean 'translucent'?)",
        ),
        (
            ("-m", "ssdgs", "-s", "mini", "--variant", "ablaton-B"),
            "no preset ablaton-B (did you mean 'ablation-B'",
        ),
        (
            ("-m", "ssdgs", "-s", "mini", "--ablation", "component"),
            "no ablation grid 'component' (did you mean 'components'?)",
        ),
    ],
)
def test_suites_scenes_variants_and_grids_suggest_the_close_name(args, hint):
    result = dry_run(*args)
    assert result.exit_code == 2 and hint in result.output, result.output


def test_methods_show_ignores_case_and_suggests():
    assert CliRunner().invoke(main, ["methods", "show", "GS3"]).exit_code == 0
    typo = CliRunner().invoke(main, ["methods", "show", "gs33"])
    assert typo.exit_code == 2 and "did you mean 'gs3'" in typo.output, typo.output
