"""One spelling and one behaviour per option across the verbs (#37): ``--device`` defaults to
``auto`` and resolves through one helper, ``--resolution`` takes ``N|WxH`` everywhere, help texts
carry no reST markup and runnable examples, hidden old spellings are never suggested, and progress
bars write plain lines into logs."""

from __future__ import annotations

import io
import re
import shlex
from pathlib import Path

import click
import pytest
import test_runner_support as support
from click.testing import CliRunner

from olatbench.cli import main
from olatbench.datasets import suites
from olatbench.devices import resolve_device
from olatbench.progress import PlainProgress, progress_bar

TORCH_VERBS = [["run"], ["render"], ["view"]]
RESOLUTION_VERBS = [
    (["run"], ["-m", "x", "-s", "y"], "resolution"),
    (["render"], ["."], "resolution"),
    (["datasets", "synth"], [], "res"),
]


def _command(path: list[str]) -> click.Command:
    command, context = main, click.Context(main)
    for name in path:
        command = command.get_command(context, name)
    return command


def _every_verb(command: click.Command = main, path: tuple[str, ...] = ()):
    if isinstance(command, click.Group):
        context = click.Context(command)
        for name in command.list_commands(context):
            yield from _every_verb(command.get_command(context, name), (*path, name))
    else:
        yield list(path)


@pytest.mark.parametrize("verb", TORCH_VERBS)
def test_device_defaults_to_auto_on_every_verb_that_renders_or_trains(verb):
    (device,) = [param for param in _command(verb).params if param.name == "device"]
    assert device.default == "auto"
    assert "[default: auto]" in CliRunner().invoke(main, [*verb, "--help"]).output


def test_auto_resolves_to_what_torch_sees():
    import torch

    from olatbench.devices import DeviceError

    assert resolve_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")
    assert resolve_device("cpu") == "cpu"
    # a device torch lacks here
    beyond = f"cuda:{torch.cuda.device_count() if torch.cuda.is_available() else 0}"
    with pytest.raises(DeviceError, match=f"device '{beyond}' is not usable here"):
        resolve_device(beyond)


@pytest.mark.parametrize(("verb", "required", "param"), RESOLUTION_VERBS)
def test_resolution_takes_n_and_wxh_everywhere(verb, required, param):
    command = _command(verb)
    for given, size in (("64", (64, 64)), ("96x64", (96, 64)), ("96X64", (96, 64))):
        assert (
            command.make_context(verb[-1], [*required, "--resolution", given]).params[param] == size
        ), given
    assert "N|WxH" in CliRunner().invoke(main, [*verb, "--help"]).output
    bad = CliRunner().invoke(main, [*verb, *required, "--resolution", "big"])
    assert bad.exit_code == 2 and "expected N or WxH" in bad.output


def test_help_texts_carry_no_double_backtick_markup():
    marked = {
        " ".join(verb): line.strip()
        for verb in _every_verb()
        for line in CliRunner().invoke(main, [*verb, "--help"]).output.splitlines()
        if "``" in line
    }
    assert not marked


def test_the_evaluate_example_names_a_scene_that_exists(monkeypatch):
    # the example names the default cache (a path compared, nothing read)
    monkeypatch.delenv("XDG_CACHE_HOME")
    text = CliRunner().invoke(main, ["evaluate", "--help"]).output
    example = " ".join(
        line.strip().rstrip("\\")
        for line in text.split("Example:")[1].split("Options:")[0].splitlines()
    )
    words = shlex.split(example)
    renders, truth = Path(words[2]), Path(words[words.index("--gt") + 1])
    mini = suites.SUITES["mini"]
    assert truth.name in mini.scenes and renders.parts[:2] == ("runs", "mini")
    # runs/<suite>/<method>/<variant>/<scene>/seed<k>/renders/<split>
    assert renders.parts[4] == truth.name
    assert Path(truth.parent).expanduser() == mini_root()


def mini_root() -> Path:
    from olatbench.datasets.synth.mini import default_root

    return default_root()


@pytest.mark.parametrize(
    ("verb", "required", "typo", "shown", "hidden"),
    [
        (["run"], ["-m", "x", "-s", "y"], "--outpt", "--output", "--out"),
        (["datasets", "synth"], [], "--resolutin", "--resolution", "--res"),
    ],
)
def test_a_mistyped_option_is_offered_the_shown_spelling_only(verb, required, typo, shown, hidden):
    result = CliRunner().invoke(main, [*verb, *required, typo, "x"])
    assert result.exit_code == 2 and "No such option" in result.output
    suggestions = result.output.split("Did you mean", 1)[1]
    assert shown in suggestions and not re.search(rf"'{hidden}'", suggestions)


def test_a_bad_value_names_the_shown_spelling_only():
    result = CliRunner().invoke(main, ["datasets", "synth", "--res", "big"])
    assert (
        result.exit_code == 2
        and "'--resolution'" in result.output
        and "'--res'" not in result.output
    )


def test_nested_progress_bars_write_plain_lines_into_a_file():
    log = io.StringIO()
    with progress_bar(total=3, desc="jobs", position=0, file=log) as jobs:
        for job in range(3):
            for _ in progress_bar(range(20), desc=f"job {job}", position=1, leave=False, file=log):
                pass
            jobs.set_postfix_str(f"job {job}")
            jobs.update(1)
    text = log.getvalue()
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    assert lines[0].startswith("jobs: 0/3 it (0%)") and lines[-1].startswith("jobs: 3/3 it (100%)")
    assert "job 1: 20/20 it (100%)" in text and all(line.strip() for line in lines)
    assert sum(line.startswith("job 2:") for line in lines) <= 12  # a line per tenth, not per step


def test_a_plain_bar_of_quick_work_writes_a_start_line_and_a_summary():
    """Off a terminal, validating 36 frames in a few seconds is two lines (it was one per tenth: 11
    lines)."""
    log = io.StringIO()
    for _ in PlainProgress(range(36), desc="validate", unit="frame", file=log):
        pass
    lines = log.getvalue().splitlines()
    assert [line.split(" 0:")[0] for line in lines] == [
        "validate: 0/36 frame (0%)",
        "validate: 36/36 frame (100%)",
    ]


def test_a_plain_bar_of_long_work_writes_at_most_a_line_per_tenth():
    """With ``interval`` passed between every update (0 s here), a line per tenth done, never
    more."""
    log = io.StringIO()
    bar = PlainProgress(total=1000, desc="steps", file=log, interval=0.0)
    for _ in range(1000):
        bar.update(1)
    bar.close()
    lines = log.getvalue().splitlines()
    assert len(lines) == 1 + 10 and lines[5].startswith("steps: 500/1000")
    untimed = io.StringIO()
    # no total: a line per interval
    heartbeat = PlainProgress(desc="download", file=untimed, interval=0.0)
    heartbeat.update(3)
    heartbeat.close()
    assert len(untimed.getvalue().splitlines()) == 2


def test_a_run_into_a_log_file_has_no_carriage_returns_or_cursor_codes(tmp_path, monkeypatch):
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite())
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    data = support.write_tiny_data(tmp_path / "data")
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            "trivial",
            "-s",
            "tiny",
            "--data-root",
            str(data),
            "-o",
            str(tmp_path / "runs"),
            "--device",
            "cpu",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "jobs:" in result.stderr and "Alpha" in result.stderr  # the bars were there, as lines
    assert "\r" not in result.stderr and "\x1b" not in result.stderr


def test_one_size_parser_for_options_and_project_files() -> None:
    """`--resolution` and a suite's ``resolution`` in olatbench.toml accept the same text forms."""
    from olatbench.cli.options import Resolution
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.suites import parse_resolution

    for text, size in (("256", (256, 256)), ("320x240", (320, 240)), (" 320X240 ", (320, 240))):
        assert Resolution().convert(text, None, None) == size == parse_resolution(text, "f")
    for text in ("256x", "x240", "big", "1x2x3"):
        with pytest.raises(click.BadParameter, match="expected N or WxH"):
            Resolution().convert(text, None, None)
        with pytest.raises(DatasetError, match="resolution must be N, WxH"):
            parse_resolution(text, "f")
