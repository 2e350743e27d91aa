"""Sweep videos: H.264 through PyAV or imageio-ffmpeg (checked by decoding the file with PyAV), the
stated mp4v fallback, `olatbench render` writing H.264, and the HTML report embedding a video a
browser plays."""

from __future__ import annotations

import logging
import re
import shutil
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner
from test_render_sweep import make_job
from test_report_snapshots import toy_runs
from waiting import BACKSTOP_SECONDS

from olatbench.cli import main
from olatbench.reports import encode

av = pytest.importorskip("av", reason="PyAV (olatbench[video]) decodes the written files")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def gradient_frames(count: int, width: int, height: int) -> list[np.ndarray]:
    """Smooth colour ramps that move from frame to frame (uint8 RGB)."""
    y, x = np.mgrid[0:height, 0:width]
    return [
        np.stack(
            [
                (x * 255 // max(width - 1, 1) + 20 * t) % 256,
                y * 255 // max(height - 1, 1),
                np.full_like(x, 40 * t % 256),
            ],
            axis=2,
        ).astype(np.uint8)
        for t in range(count)
    ]


def decode(path) -> tuple[str, str, list[np.ndarray]]:
    """(codec name, pixel format, RGB frames) of the first video stream, as PyAV reads it."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = [frame.to_ndarray(format="rgb24") for frame in container.decode(stream)]
        return stream.codec_context.name, stream.codec_context.pix_fmt, frames


@pytest.mark.parametrize("encoder", ["av", "imageio-ffmpeg"])
def test_h264_encoders_write_a_playable_stream(tmp_path, encoder):
    """Odd sizes are padded to even (yuv420p); the decoded frames match the input up to
    compression."""
    if encoder not in encode.available_encoders():
        pytest.skip(f"{encoder} is not installed")
    frames = gradient_frames(5, 17, 13)
    writer = encode.open_video(tmp_path / "v.mp4", 10.0, 17, 13, encoder=encoder)
    for frame in frames:
        writer.write(frame)
    writer.close()
    codec, pix_fmt, decoded = decode(tmp_path / "v.mp4")
    assert (codec, pix_fmt, writer.encoder) == ("h264", "yuv420p", encoder)
    assert len(decoded) == 5 and decoded[0].shape == (14, 18, 3)
    error = np.abs(decoded[2][:13, :17].astype(float) - frames[2]).mean()
    # chroma subsampling of a 17×13 ramp; a wrong channel order would be ~80
    assert error < 6.0, error


def test_without_an_h264_encoder_mp4v_is_written_and_logged(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(encode, "available_encoders", lambda: ["opencv"])
    with caplog.at_level(logging.WARNING, logger="olatbench.reports.encode"):
        writer = encode.open_video(tmp_path / "v.mp4", 10.0, 16, 12)
        for frame in gradient_frames(3, 16, 12):
            writer.write(frame)
        writer.close()
    assert writer.encoder == "opencv" and "browsers do not play" in caplog.text
    codec, _, decoded = decode(tmp_path / "v.mp4")
    assert codec == "mpeg4" and len(decoded) == 3


def test_unknown_encoder_is_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown video encoder"):
        encode.open_video(tmp_path / "v.mp4", 10.0, 16, 12, encoder="gif")


def test_cli_render_writes_h264(tmp_path):
    folder = make_job(tmp_path)
    result = CliRunner().invoke(
        main, ["render", str(folder), "--frames", "4", "-o", str(tmp_path / "video")]
    )
    assert result.exit_code == 0, result.output
    assert "H.264" in result.output
    codec, _, decoded = decode(tmp_path / "video" / "light-orbit.mp4")
    assert codec == "h264" and len(decoded) == 4


def _report_with_video(tmp_path, encoder: str = "av"):
    runs = toy_runs(tmp_path)
    job = next(runs.rglob("results.json")).parent
    (job / "videos").mkdir()
    writer = encode.open_video(job / "videos" / "light-orbit.mp4", 10.0, 32, 24, encoder=encoder)
    for frame in gradient_frames(10, 32, 24):
        writer.write(frame)
    writer.close()
    page = tmp_path / "report.html"
    result = CliRunner().invoke(main, ["report", str(runs), "--suite", "nrhints", "-o", str(page)])
    assert result.exit_code == 0, result.output
    return page


def test_html_report_embeds_h264_sweeps_and_notes_mp4v(tmp_path):
    html = _report_with_video(tmp_path / "h264").read_text()
    assert (
        html.count("<video") == 1
        and 'src="data:video/mp4;base64,' in html
        and "light-orbit sweep" in html
    )
    html = _report_with_video(tmp_path / "mp4v", encoder="opencv").read_text()
    assert "<video" not in html and "light-orbit.mp4 is not H.264" in html


PROBE = """<script>
const video = document.querySelector("video");
const report = (text) => { document.body.setAttribute("data-probe", text); };
video.addEventListener("loadeddata", () => report(`played ${video.videoWidth}x${video.videoHeight}`));
video.addEventListener("error", () => report(`error ${video.error && video.error.code}`));
video.load();
</script>"""  # noqa: E501


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
def test_chromium_plays_the_embedded_video(tmp_path):
    """Headless Chromium decodes the report's video (`loadeddata` with the right size); the same
    page with an mp4v file embedded fails to decode, which is what the fallback note warns about."""
    page = _report_with_video(tmp_path)
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text().replace("</body>", PROBE + "</body>"))
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--autoplay-policy=no-user-gesture-required",
        "--virtual-time-budget=10000",
        "--dump-dom",
    ]
    dom = subprocess.run(
        [CHROMIUM, *flags, probe.as_uri()], capture_output=True, text=True, timeout=BACKSTOP_SECONDS
    ).stdout
    assert re.search(r'data-probe="played 32x24"', dom), dom[-2000:]
