"""Stand-in checkouts of the official implementations, for tests: tiny script trees that obey the same command
lines as the real code, read the converted scene exactly where the official loader reads it, and write renders
where and how the official render script writes them. (Written from the documented behaviour recorded in
`olatbench.methods.official.specs`, not from the authors' code.)

Their "model" is perfect: the render of a test frame is its ground truth composited on the background (as the
official loaders composite), so a correctly mapped and decoded render scores far above a mismatched one.

Control files in the checkout: ``FAIL`` makes the train step print 40 lines and exit 3 (when its text, maybe
empty, is part of the command line); ``SLOW`` makes it write
its pid to ``started`` and sleep ``SLOW``'s number of seconds; ``SHIFT`` makes the render step write frame i+1's
image as render i (a wrong frame mapping).
"""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

LIB = textwrap.dedent('''
    """Shared by the stand-in scripts (not the authors' code)."""
    import json, os, sys, time
    from pathlib import Path
    import numpy as np
    from olatbench.datasets.images import read_image, write_image

    CHECKOUT = Path(__file__).resolve().parent

    def control():
        if (CHECKOUT / "FAIL").exists() and (CHECKOUT / "FAIL").read_text() in " ".join(sys.argv):
            for i in range(40):
                print(f"training line {i}")
            print("RuntimeError: CUDA out of memory", file=sys.stderr)
            sys.exit(3)
        if (CHECKOUT / "SLOW").exists():
            (CHECKOUT / "started").write_text(str(os.getpid()))
            time.sleep(float((CHECKOUT / "SLOW").read_text() or 60))

    def frames(scene, split):
        return json.loads((Path(scene) / f"transforms_{split}.json").read_text())["frames"]

    def perfect(scene, frame, ext, white, gamma=False):
        """The frame's image as a perfect model renders it: composited on the background where the loader
        composites (linear premultiplied EXR, or straight 8-bit PNG), then x^(1/2.2) if gamma."""
        path = Path(scene) / (frame["file_path"] + ext)
        assert path.is_file(), f"the loader reads {path}, which is missing"
        image = read_image(path)
        rgb, alpha = image[..., :3], image[..., 3:4]
        background = 1.0 if white else 0.0
        out = rgb + background * (1 - alpha) if ext == ".exr" else rgb * alpha + background * (1 - alpha)
        return np.clip(out, 0, 1) ** (1 / 2.2) if gamma else np.clip(out, 0, 1)

    def write_renders(scene, out_dir, name, ext, white, gamma=False):
        test = frames(scene, "test")
        shift = 1 if (CHECKOUT / "SHIFT").exists() else 0
        for index in range(len(test)):
            frame = test[(index + shift) % len(test)]
            write_image(Path(out_dir) / name.format(index=index), perfect(scene, frame, ext, white, gamma), "uint8")
''')

# GS³ / SSD-GS: 3DGS-style train.py (-s, -m, flags) and render.py (-m, reads the model's stored arguments).
GAUSSIAN_TRAIN = textwrap.dedent('''
    import argparse, json
    from pathlib import Path
    import standin_lib as lib
    FLAGS = {flags!r}
    SWITCHES = {switches!r}
    parser = argparse.ArgumentParser()
    parser.add_argument("-s", "--source_path", required=True)
    parser.add_argument("-m", "--model_path", required=True)
    for name in FLAGS:
        parser.add_argument(name)
    for name in SWITCHES:
        parser.add_argument(name, action="store_true")
    args = parser.parse_args()
    lib.control()
    ext = ".exr" if getattr(args, "hdr", False) else ".png"
    for split in ("train", "test"):
        for frame in lib.frames(args.source_path, split):
            assert (Path(args.source_path) / (frame["file_path"] + ext)).is_file()
    model = Path(args.model_path)
    model.mkdir(parents=True, exist_ok=True)
    (model / "cfg.json").write_text(json.dumps(vars(args)))
    if getattr(args, "cam_opt", False):  # the refined poses the render step reads with --opt_pose
        (model / "point_cloud" / f"iteration_{{args.iterations}}").mkdir(parents=True)
    print(f"trained {{args.iterations}} iterations on {{args.source_path}}")
''')

GAUSSIAN_RENDER = textwrap.dedent('''
    import argparse, json
    from pathlib import Path
    import standin_lib as lib
    parser = argparse.ArgumentParser()
    parser.add_argument("-m", "--model_path", required=True)
    parser.add_argument("--iteration", type=int, default=-1)
    for name in ("--skip_train", "--skip_test", "--quiet", "--gamma", "--opt_pose", "--valid",
                 "--use_nerual_phasefunc"):
        parser.add_argument(name, action="store_true")
    args = parser.parse_args()
    model = Path(args.model_path)
    trained = json.loads((model / "cfg.json").read_text())
    if args.opt_pose:
        assert (model / "point_cloud" / f"iteration_{args.iteration}").is_dir(), "opt_pose needs cam_opt training"
    out = model / "test" / f"ours_{args.iteration}" / "renders"
    lib.write_renders(trained["source_path"], out, "{index:05d}.png", ".exr" if trained.get("hdr") else ".png",
                      trained.get("white_background", False), args.gamma)
    print(f"rendered to {out}")
''')

GS3_FLAGS = ["--view_num", "--iterations", "--asg_freeze_step", "--spcular_freeze_step", "--fit_linear_step",
             "--asg_lr_freeze_step", "--asg_lr_max_steps", "--asg_lr_init", "--asg_lr_final",
             "--local_q_lr_freeze_step", "--local_q_lr_init", "--local_q_lr_final", "--local_q_lr_max_steps",
             "--neural_phasefunc_lr_init", "--neural_phasefunc_lr_final", "--freeze_phasefunc_steps",
             "--neural_phasefunc_lr_max_steps", "--unfreeze_iterations", "--save_iterations",
             "--checkpoint_iterations", "--position_lr_max_steps", "--densify_until_iter", "--data_device",
             "--densify_grad_threshold"]
GS3_SWITCHES = ["--use_nerual_phasefunc", "--eval", "--hdr", "--white_background", "--cam_opt", "--pl_opt"]
SSDGS_FLAGS = [name.replace("spcular", "specular") for name in GS3_FLAGS]
SSDGS_SWITCHES = ["--use_nerual_phasefunc", "--eval", "--white_background", "--cam_opt", "--pl_opt"]

# NRHints: main.py <tyro sub-command> --config.<a>.<b> VALUE ...; renders after training.
NRHINTS_MAIN = textwrap.dedent('''
    import sys
    from pathlib import Path
    import standin_lib as lib
    command, rest = sys.argv[1], sys.argv[2:]
    assert command in ("config:nr-hints", "config:nr-hints-cam-opt", "config:pl-naive"), command
    assert len(rest) % 2 == 0 and all(key.startswith("--config.") for key in rest[::2]), rest
    config = dict(zip(rest[::2], rest[1::2]))
    known = {"--config.data.path", "--config.scene-name", "--config.base-dir", "--config.exp-name",
             "--config.model.end-iter", "--config.data.white-background", "--config.data.view-num-limit"}
    assert set(config) <= known, set(config) - known
    white = {"True": True, "False": False}[config.get("--config.data.white-background", "True")]
    lib.control()
    scene = config["--config.data.path"]
    for split in ("train", "val", "test"):
        for frame in lib.frames(scene, split):
            assert (Path(scene) / (frame["file_path"] + frame.get("file_ext", ".png"))).is_file()
    end = int(config["--config.model.end-iter"])
    log_dir = Path(config["--config.base-dir"]) / config["--config.exp-name"] / config["--config.scene-name"]
    lib.write_renders(scene, log_dir / "test_views" / f"step_{end:07d}", "rgb_{index:03d}.png", ".png", white)
    print(f"trained to {end} and rendered into {log_dir}")
''')

# A container runtime stub: `<stub> run [options] IMAGE python ARGS...` runs ARGS with this interpreter in -w.
RUNTIME_STUB = textwrap.dedent('''
    import os, sys
    args = sys.argv[1:]
    assert args[0] in ("run", "exec"), args
    image = args.index("olatbench/official:test")
    options, command = args[1:image], args[image + 1:]
    assert command[0] == "python", command
    workdir = options[options.index("-w") + 1] if "-w" in options else os.getcwd()
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "invocations.txt"), "a") as log:
        log.write(" ".join(args) + "\\n")
    os.chdir(workdir)
    os.execv(sys.executable, [sys.executable, *command[1:]])
''')


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def write_checkout(root: Path, code: str, git: bool = False) -> Path:
    """A stand-in checkout of ``code`` ("gs3-official", "ssdgs-official" or "nrhints-official") at ``root``;
    ``git`` makes it a git repository with one commit."""
    root.mkdir(parents=True, exist_ok=True)
    _write(root / "standin_lib.py", LIB)
    if code == "nrhints-official":
        _write(root / "main.py", NRHINTS_MAIN)
    else:
        flags, switches = ((GS3_FLAGS, GS3_SWITCHES) if code == "gs3-official" else (SSDGS_FLAGS, SSDGS_SWITCHES))
        _write(root / "train.py", GAUSSIAN_TRAIN.format(flags=flags, switches=switches))
        _write(root / "render.py", GAUSSIAN_RENDER)
    if git:
        env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
               "GIT_COMMITTER_EMAIL": "t@t"}
        for argv in (["init", "-q"], ["add", "."], ["commit", "-q", "-m", "stand-in"]):
            subprocess.run(["git", "-C", str(root), *argv], check=True, env=env, capture_output=True)
    return root


def write_runtime_stub(path: Path) -> Path:
    """An executable container-runtime stub (see `RUNTIME_STUB`); its calls are appended to invocations.txt."""
    _write(path, f"#!{sys.executable}\n" + RUNTIME_STUB)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path
