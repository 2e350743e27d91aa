"""Stand-in checkouts of the official implementations, for tests: tiny script trees that obey the
same command lines as the real code, read the converted scene exactly where the official loader
reads it, and write renders where and how the official render script writes them. (Written from the
behaviour recorded, with file and line, in `olatbench.methods.official.specs`, not copied from the
authors' code.) Behaviours that decide whether olatbench scores the right images are reproduced:
SSD-GS / GS³ ``train.py`` with ``--cam_opt``/``--pl_opt`` shuffles the test cameras with ``random``
seeded to 0 (after the train cameras) and saves them in that order to
``point_cloud/iteration_<it>/transforms_test.json`` (``file_path`` = image stem, ``img_path``,
``R_opt``/``T_opt``), which ``render.py --opt_pose`` renders in its order; the NRHints parser takes
one camera model (top-level intrinsics, ``camera_near``/``camera_far`` defaulting to 3 and 10) from
the first split's file and prints it.

Their "model" is perfect: the render of a test frame is its ground truth composited on the
background (as the official loaders composite), so a correctly mapped and decoded render scores far
above a mismatched one.

Control files in the checkout: ``FAIL`` makes the train step print 40 lines and exit 3 (when its
text, maybe empty, is part of the command line); ``SLOW`` makes it write its pid to ``started`` and
sleep ``SLOW``'s number of seconds; ``SHIFT`` makes the render step write frame i+1's image as
render i (a wrong frame mapping).
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
        """Render the frames of the scene's transforms_test.json in its order (the loader's order)."""
        test = frames(scene, "test")
        shift = 1 if (CHECKOUT / "SHIFT").exists() else 0
        for index in range(len(test)):
            frame = test[(index + shift) % len(test)]
            if "img_path" in frame:  # a saved camera file: the image is named by its path, extension included
                frame = {"file_path": str(Path(frame["img_path"]).with_suffix(""))}
            write_image(Path(out_dir) / name.format(index=index), perfect(scene, frame, ext, white, gamma), "uint8")

    def save_refined_cameras(scene, model, iteration, ext):
        """As SSD-GS/GS³ train.py with --cam_opt/--pl_opt: safe_state seeds random with 0, Scene(shuffle=True)
        shuffles the train cameras, then the test cameras, and Scene.save writes each split in that order."""
        import random
        random.seed(0)
        out = Path(model) / "point_cloud" / f"iteration_{iteration}"
        out.mkdir(parents=True, exist_ok=True)
        for split in ("train", "test"):
            cams = []
            for frame in frames(scene, split):
                image = Path(scene).resolve() / (frame["file_path"] + ext)
                c2w = np.array(frame["transform_matrix"], dtype=float)
                c2w[:3, 1:3] *= -1
                w2c = np.linalg.inv(c2w)
                cams.append({"file_path": image.stem, "img_path": str(image), "R_opt": w2c[:3, :3].T.tolist(),
                             "T_opt": w2c[:3, 3].tolist(), "pl_pos": frame["pl_pos"]})
            random.shuffle(cams)
            (out / f"transforms_{split}.json").write_text(json.dumps({"frames": cams}))
''')  # noqa: E501

# GS³ / SSD-GS: 3DGS-style train.py (-s, -m, flags) and render.py (-m, reads the model's stored
# arguments).
GAUSSIAN_TRAIN = textwrap.dedent("""
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
    if getattr(args, "cam_opt", False) or getattr(args, "pl_opt", False):  # what render.py --opt_pose reads
        lib.save_refined_cameras(args.source_path, model, args.iterations, ext)
    print(f"trained {{args.iterations}} iterations on {{args.source_path}}")
""")  # noqa: E501

GAUSSIAN_RENDER = textwrap.dedent("""
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
    source = trained["source_path"]
    if args.opt_pose:  # render.py: source_path becomes the saved cameras' folder
        source = model / "point_cloud" / f"iteration_{args.iteration}"
        assert (source / "transforms_test.json").is_file(), "opt_pose needs cam_opt/pl_opt training"
    out = model / "test" / f"ours_{args.iteration}" / "renders"
    lib.write_renders(source, out, "{index:05d}.png", ".exr" if trained.get("hdr") else ".png",
                      trained.get("white_background", False), args.gamma)
    print(f"rendered to {out}")
""")

GS3_FLAGS = [
    "--view_num",
    "--iterations",
    "--asg_freeze_step",
    "--spcular_freeze_step",
    "--fit_linear_step",
    "--asg_lr_freeze_step",
    "--asg_lr_max_steps",
    "--asg_lr_init",
    "--asg_lr_final",
    "--local_q_lr_freeze_step",
    "--local_q_lr_init",
    "--local_q_lr_final",
    "--local_q_lr_max_steps",
    "--neural_phasefunc_lr_init",
    "--neural_phasefunc_lr_final",
    "--freeze_phasefunc_steps",
    "--neural_phasefunc_lr_max_steps",
    "--unfreeze_iterations",
    "--save_iterations",
    "--checkpoint_iterations",
    "--position_lr_max_steps",
    "--densify_until_iter",
    "--data_device",
    "--densify_grad_threshold",
]
GS3_SWITCHES = [
    "--use_nerual_phasefunc",
    "--eval",
    "--hdr",
    "--white_background",
    "--cam_opt",
    "--pl_opt",
]
SSDGS_FLAGS = [name.replace("spcular", "specular") for name in GS3_FLAGS]
SSDGS_SWITCHES = ["--use_nerual_phasefunc", "--eval", "--white_background", "--cam_opt", "--pl_opt"]

# RNG: train.py runs stage 1 (no --load_pc) or stage 2 (--load_pc <model>/chkpnt<it>.pth, which must
# exist) and saves <model>/chkpnt<iterations>.pth (train.py:186); render.py reads the arguments
# train.py stored (cfg_args, render.py:335) and renders the test frames in the loader's order. Each
# call is appended to calls.txt.
RNG_TRAIN = textwrap.dedent("""
    import argparse, json
    from pathlib import Path
    import standin_lib as lib
    parser = argparse.ArgumentParser()
    parser.add_argument("-s", "--source_path", required=True)
    parser.add_argument("-m", "--model_path", required=True)
    for name in {flags!r}:
        parser.add_argument(name)
    for name in {switches!r}:
        parser.add_argument(name, action="store_true")
    args = parser.parse_args()
    with open(lib.CHECKOUT / "calls.txt", "a") as calls:
        calls.write(("stage2" if args.load_pc else "stage1") + "\\n")
    lib.control()
    for split in ("train", "test"):
        for frame in lib.frames(args.source_path, split):
            assert (Path(args.source_path) / (frame["file_path"] + frame["file_ext"])).is_file()
    model = Path(args.model_path)
    if args.load_pc:
        assert Path(args.load_pc).is_file(), f"stage 2 loads {{args.load_pc}}, which stage 1 did not write"
        assert int(Path(args.load_pc).read_text()) < int(args.iterations)
    model.mkdir(parents=True, exist_ok=True)
    (model / "cfg.json").write_text(json.dumps(vars(args)))
    (model / f"chkpnt{{args.iterations}}.pth").write_text(args.iterations)
    print(f"trained to {{args.iterations}} on {{args.source_path}}")
""")  # noqa: E501

RNG_RENDER = textwrap.dedent("""
    import argparse, json
    from pathlib import Path
    import standin_lib as lib
    parser = argparse.ArgumentParser()
    parser.add_argument("-m", "--model_path", required=True)
    parser.add_argument("--iteration", type=int, default=-1)
    for name in ("--in_channels", "--depth_mlp_modifier", "--encoding_levels_each", "--encoding_levels_shadow",
                 "--max_reso", "--crop_pc"):
        parser.add_argument(name)
    for name in ("--skip_train", "--eval", "--json", "--color_mlp", "--defer_shading", "--shadow_map",
                 "--depth_mlp"):
        parser.add_argument(name, action="store_true")
    args = parser.parse_args()
    with open(lib.CHECKOUT / "calls.txt", "a") as calls:
        calls.write("render\\n")
    trained = json.loads((Path(args.model_path) / "cfg.json").read_text())
    assert trained["load_pc"] and int(trained["iterations"]) == args.iteration, trained
    out = Path(args.model_path) / "test" / f"ours_{args.iteration}" / "renders"
    lib.write_renders(trained["source_path"], out, "{index:05d}.png", ".png", trained["white_background"])
    # render.py:82 saves the ground truth of each view it rendered beside it (SHIFT: of the frame it rendered)
    lib.write_renders(trained["source_path"], out.parent / "gt", "{index:05d}.png", ".png",
                      trained["white_background"])
    print(f"rendered to {out}")
""")  # noqa: E501
RNG_FLAGS = [
    "--iterations",
    "--save_iterations",
    "--densify_until_iter",
    "--densify_from_iter",
    "--opacity_reset_interval",
    "--position_lr_max_steps",
    "--in_channels",
    "--max_training_images",
    "--max_reso",
    "--loss",
    "--load_pc",
    "--depth_mlp_modifier",
    "--encoding_levels_each",
    "--encoding_levels_shadow",
    "--crop_pc",
]
RNG_SWITCHES = [
    "--eval",
    "--json",
    "--color_mlp",
    "--defer_shading",
    "--shadow_map",
    "--shadow_grad",
    "--depth_mlp",
    "--white_background",
]

# NRHints: main.py <tyro sub-command> --config.<a>.<b> VALUE ...; renders after training.
NRHINTS_MAIN = textwrap.dedent("""
    import json, sys
    from pathlib import Path
    import standin_lib as lib
    command, rest = sys.argv[1], sys.argv[2:]
    assert command in ("config:nr-hints", "config:nr-hints-cam-opt", "config:pl-naive"), command
    assert len(rest) % 2 == 0 and all(key.startswith("--config.") for key in rest[::2]), rest
    config = dict(zip(rest[::2], rest[1::2]))
    known = {"--config.data.path", "--config.scene-name", "--config.base-dir", "--config.exp-name",
             "--config.model.end-iter", "--config.data.white-background", "--config.data.view-num-limit",
             "--config.model.geometry-warmup-end"}
    assert set(config) <= known, set(config) - known
    white = {"True": True, "False": False}[config.get("--config.data.white-background", "True")]
    lib.control()
    scene = config["--config.data.path"]
    first = json.loads((Path(scene) / "transforms_train.json").read_text())  # data_parser.py: metas[splits[0]]
    zn, zf = first.get("camera_near", 3.0), first.get("camera_far", 10.0)
    intrinsics = first["camera_intrinsics"] if "camera_intrinsics" in first else first["camera_angle_x"]
    print(f"camera model: intrinsics {intrinsics}, zn {zn}, zf {zf}")
    for split in ("train", "val", "test"):
        for frame in lib.frames(scene, split):
            assert (Path(scene) / (frame["file_path"] + frame.get("file_ext", ".png"))).is_file()
    end = int(config["--config.model.end-iter"])
    log_dir = Path(config["--config.base-dir"]) / config["--config.exp-name"] / config["--config.scene-name"]
    lib.write_renders(scene, log_dir / "test_views" / f"step_{end:07d}", "rgb_{index:03d}.png", ".png", white)
    print(f"trained to {end} and rendered into {log_dir}")
""")  # noqa: E501

# A container runtime stub: `<stub> run [options] IMAGE python ARGS...` runs ARGS with this
# interpreter in -w.
RUNTIME_STUB = textwrap.dedent("""
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
""")  # noqa: E501


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def write_checkout(root: Path, code: str, git: bool = False) -> Path:
    """A stand-in checkout of ``code`` ("gs3-official", "ssdgs-official", "nrhints-official" or
    "rng-official") at ``root``; ``git`` makes it a git repository with one commit."""
    root.mkdir(parents=True, exist_ok=True)
    _write(root / "standin_lib.py", LIB)
    if code == "nrhints-official":
        _write(root / "main.py", NRHINTS_MAIN)
    elif code == "rng-official":
        _write(root / "train.py", RNG_TRAIN.format(flags=RNG_FLAGS, switches=RNG_SWITCHES))
        _write(root / "render.py", RNG_RENDER)
    else:
        flags, switches = (
            (GS3_FLAGS, GS3_SWITCHES) if code == "gs3-official" else (SSDGS_FLAGS, SSDGS_SWITCHES)
        )
        _write(root / "train.py", GAUSSIAN_TRAIN.format(flags=flags, switches=switches))
        _write(root / "render.py", GAUSSIAN_RENDER)
    if git:
        env = {
            **os.environ,
            "GIT_AUTHOR_NAME": "t",
            "GIT_AUTHOR_EMAIL": "t@t",
            "GIT_COMMITTER_NAME": "t",
            "GIT_COMMITTER_EMAIL": "t@t",
        }
        for argv in (["init", "-q"], ["add", "."], ["commit", "-q", "-m", "stand-in"]):
            subprocess.run(
                ["git", "-C", str(root), *argv], check=True, env=env, capture_output=True
            )
    return root


def write_runtime_stub(path: Path) -> Path:
    """An executable container-runtime stub (see `RUNTIME_STUB`); its calls are appended to
    invocations.txt."""
    _write(path, f"#!{sys.executable}\n" + RUNTIME_STUB)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path
