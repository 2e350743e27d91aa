"""The official implementations olatbench knows, as `OfficialCode` (how to run it) and `MethodSpec`
(what the registry lists): ``ssdgs-official``, ``gs3-official``, ``nrhints-official``,
``rng-official`` run; ``gigs-official``, ``tensoir-official`` and ``r3dg-official`` are listed with
the reason they cannot be run.

"Verified" here means: the repository and the pinned commit exist (a git mirror of the repository
was read at that commit on 2026-11-24), every flag of the commands below was found in that commit's
argument parsers, the scene files are written where that commit's loader reads them and the renders
are read where its render script writes them. None of them was run on a GPU from here;
docs/official.md says how to check one that was.
"""

from __future__ import annotations

from olatbench.methods.official.code import ANY_SUITE, SUITE_ARGS, OfficialCode, SceneArgs
from olatbench.methods.spec import MethodSpec, SourcePin

_CONFIG = "olatbench.methods.official.code:OfficialConfig"
_MODULE = "olatbench.methods.official.specs"

# With --cam_opt/--pl_opt, train.py builds Scene(shuffle=True), which shuffles the test cameras with
# the seeded `random` of safe_state (scene/__init__.py:75-77), and Scene.save writes them in that
# order, with the refined poses, to this file (scene/__init__.py:153-199); render.py --opt_pose
# renders exactly its frames, in its order, as 00000.png, 00001.png, ... The entries name their
# image by file_path (the stem) and img_path.
_REFINED_CAMERAS = "{model}/point_cloud/iteration_{iterations}/transforms_test.json"

# The train scripts' iteration-valued options and their parser defaults (OptimizationParams in
# arguments/__init__.py:90-167 at both commits, train.py's --unfreeze_iterations default 0), scaled
# in runs shorter than the scripts' (OfficialConfig.reference_iterations; the mini presets below).
# Not scaled: the densification interval (a cadence, as in the native presets) and train.py's fixed
# `iteration % 1000` SH step, which is unused with --use_nerual_phasefunc (train.py:92-94 SSD-GS,
# 87-89 GS³).
_SCHEDULE_FLAGS = {
    "--position_lr_max_steps": 30_000,
    "--fit_linear_step": 7_000,
    "--asg_freeze_step": 22_000,
    "--asg_lr_freeze_step": 40_000,
    "--asg_lr_max_steps": 50_000,
    "--local_q_lr_freeze_step": 40_000,
    "--local_q_lr_max_steps": 50_000,
    "--freeze_phasefunc_steps": 50_000,
    "--neural_phasefunc_lr_max_steps": 50_000,
    "--opacity_reset_interval": 3_000,
    "--densify_from_iter": 500,
    "--densify_until_iter": 15_000,
    "--train_cam_freeze_step": 5_000,
    "--opt_cam_lr_delay_step": 20_000,
    "--opt_cam_lr_max_steps": 80_000,
    "--train_pl_freeze_step": 15_000,
    "--opt_pl_lr_delay_step": 30_000,
    "--opt_pl_lr_max_steps": 80_000,
    "--unfreeze_iterations": 0,
}
_SSDGS_SCHEDULE_FLAGS = {
    **_SCHEDULE_FLAGS,
    "--specular_freeze_step": 9_000,
    "--scatter_warmup_step": 9_000,
    "--scatter_freeze_step": 13_000,
    "--scatter_unfreeze_step": 20_000,
    "--scatter_lr_freeze_step": 50_000,
    "--scatter_lr_max_steps": 50_000,
}
_GS3_SCHEDULE_FLAGS = {**_SCHEDULE_FLAGS, "--spcular_freeze_step": 9_000}  # sic: GS³'s spelling
# Their Blender loader reads this file when it exists and otherwise writes 100,000 random points in
# [-0.5, 0.5]³ there (scene/dataset_readers.py:229-240 at both commits).
_POINT_CLOUD = "points3d.ply"
# The CPU-sized mini suite, as the native mini presets run it: the schedule of a 60K run compressed
# into 3000 steps, with the native mini presets' densification window, opacity reset and position
# decay (their densify_from, densify_until, opacity_reset_interval, position_lr_max_steps at the 60K
# reference) and Gaussian budget (max_gaussians: --maximum_gs, ModelParams in
# arguments/__init__.py:74, default 550,000; a test checks they agree), and 2000 initial points
# drawn in the ball fitted to the cameras, from the job's seed (docs/official.md).
_MINI_SCHEDULE = (
    "--densify_from_iter",
    "4000",
    "--densify_until_iter",
    "44000",
    "--opacity_reset_interval",
    "30000",
    "--position_lr_max_steps",
    "60000",
)
_MINI = {"iterations": 3_000, "reference_iterations": 60_000, "init_points": 2_000}

# ---- GS³ (gsrelight/gs-relight) ------------------------------------------------------------------
# Flags shared by its syn_train.sh and real_train.sh; the per-suite ones are in suite_args.
_GS3_TRAIN = (
    "train.py",
    "-s",
    "{scene}",
    "-m",
    "{model}",
    "--view_num",
    "2000",
    "--iterations",
    "{iterations}",
    "--asg_freeze_step",
    "22000",
    "--spcular_freeze_step",
    "9000",
    "--fit_linear_step",
    "7000",
    "--asg_lr_freeze_step",
    "40000",
    "--asg_lr_max_steps",
    "50000",
    "--asg_lr_init",
    "0.01",
    "--asg_lr_final",
    "0.0001",
    "--local_q_lr_freeze_step",
    "40000",
    "--local_q_lr_init",
    "0.01",
    "--local_q_lr_final",
    "0.0001",
    "--local_q_lr_max_steps",
    "50000",
    "--neural_phasefunc_lr_init",
    "0.001",
    "--neural_phasefunc_lr_final",
    "0.00001",
    "--freeze_phasefunc_steps",
    "50000",
    "--neural_phasefunc_lr_max_steps",
    "50000",
    "--unfreeze_iterations",
    "5000",
    "--save_iterations",
    "{iterations}",
    "--checkpoint_iterations",
    "{iterations}",
    "--use_nerual_phasefunc",
    "--eval",
    SUITE_ARGS,
)
_GS3_SYNTHETIC = ("--position_lr_max_steps", "50000", "--densify_until_iter", "50000")

# The scripts' per-scene flags (canonical scene names; lines of the pinned commit). The nrhints
# suite's own --densify_grad_threshold 0.0001 (Cup-Fabric's, and most light-stage scenes') is what a
# scene not listed gets. real_render.sh:71-75 also renders Fish from its 70K checkpoint rather than
# the final one; olatbench renders and scores the final iteration of every scene (docs/official.md).
_GS3_SCENES = (
    SceneArgs(
        "nrhints",
        "Pikachu",
        "train",
        ("--densify_grad_threshold", "0.00015"),
        "real_train.sh:210-240",
    ),
    SceneArgs(
        "nrhints",
        "FurScene",
        "train",
        ("--densify_grad_threshold", "0.0002"),
        "real_train.sh:242-272 (folder Cluttered)",
    ),
    SceneArgs(
        "nrhints",
        "CupFabric",
        "train",
        ("--densify_grad_threshold", "0.0001"),
        "real_train.sh:274-304 (folder Cup-Fabric)",
    ),
    SceneArgs(
        "nrhints",
        "Fish",
        "train",
        ("--densify_until_iter", "100000", "--densify_grad_threshold", "0.00012"),
        "real_train.sh:306-336",
    ),
    SceneArgs(
        "nrhints", "Cat", "train", ("--densify_grad_threshold", "0.0002"), "real_train.sh:338-368"
    ),
    SceneArgs(
        "nrhints", "Pixiu", "train", ("--densify_grad_threshold", "0.0002"), "real_train.sh:370-400"
    ),
    SceneArgs(
        "nrhints",
        "CatSmall",
        "train",
        ("--densify_grad_threshold", "0.0002"),
        "real_train.sh:402-432 (folder Cat_on_Decor)",
    ),
    SceneArgs(
        "gs3",
        "Lego",
        "train",
        (
            "--asg_freeze_step",
            "28000",
            "--spcular_freeze_step",
            "18000",
            "--fit_linear_step",
            "8000",
        ),
        "syn_train.sh:36-65",
    ),
    SceneArgs(
        "gs3",
        "Drums",
        "train",
        (
            "--asg_lr_freeze_step",
            "30000",
            "--asg_lr_max_steps",
            "70000",
            "--asg_lr_final",
            "0.0008",
            "--densify_grad_threshold",
            "0.00013",
        ),
        "syn_train.sh:126-156",
    ),
)

GS3_CODE = OfficialCode(
    name="gs3-official",
    paper=(
        "GS³: Efficient Relighting with Triple Gaussian Splatting (Bi et al., SIGGRAPH Asia 2024)"
    ),
    commands=(
        ("train", _GS3_TRAIN),
        (
            "render",
            (
                "render.py",
                "-m",
                "{model}",
                "--iteration",
                "{iterations}",
                "--skip_train",
                "--use_nerual_phasefunc",
                SUITE_ARGS,
            ),
        ),
    ),
    renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
    # render.py:60-61 reads the cameras train.py saved
    render_orders={"--opt_pose": _REFINED_CAMERAS},
    scene_args=_GS3_SCENES,
    data_formats={"gs3": "gs3", ANY_SUITE: "nrhints"},
    # render.py --gamma stores x^(1/2.2) of the linear (EXR-trained) render
    render_colourspace={"gs3": "gamma22"},
    suite_args={
        "gs3": {"train": ("--hdr", "--white_background", *_GS3_SYNTHETIC), "render": ("--gamma",)},
        "nrhints": {
            "train": (
                "--data_device",
                "cpu",
                "--cam_opt",
                "--pl_opt",
                "--position_lr_max_steps",
                "70000",
                "--densify_until_iter",
                "90000",
                "--densify_grad_threshold",
                "0.0001",
            )
        },
        ANY_SUITE: {"train": _GS3_SYNTHETIC},
    },
    # render.py:70 torch.load()s its own checkpoint (numpy scalars)
    env={"TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD": "1"},
    schedule_flags=_GS3_SCHEDULE_FLAGS,
    point_cloud=_POINT_CLOUD,
    # arguments/__init__.py:54; render.py reads it back from the model's cfg_args
    # (get_combined_args, render.py:107)
    white_background_args=("--white_background",),
)

# ---- SSD-GS (irisfreesiri/SSD-GS) ----------------------------------------------------------------
_SSDGS_TRAIN = (
    "train.py",
    "-s",
    "{scene}",
    "-m",
    "{model}",
    "--data_device",
    "cpu",
    "--view_num",
    "2000",
    "--iterations",
    "{iterations}",
    "--asg_freeze_step",
    "22000",
    "--specular_freeze_step",
    "9000",
    "--fit_linear_step",
    "7000",
    "--asg_lr_freeze_step",
    "40000",
    "--asg_lr_max_steps",
    "50000",
    "--asg_lr_init",
    "0.01",
    "--asg_lr_final",
    "0.0001",
    "--local_q_lr_freeze_step",
    "40000",
    "--local_q_lr_init",
    "0.01",
    "--local_q_lr_final",
    "0.0001",
    "--local_q_lr_max_steps",
    "50000",
    "--neural_phasefunc_lr_init",
    "0.001",
    "--neural_phasefunc_lr_final",
    "0.00001",
    "--freeze_phasefunc_steps",
    "50000",
    "--neural_phasefunc_lr_max_steps",
    "50000",
    "--unfreeze_iterations",
    "5000",
    "--save_iterations",
    "{iterations}",
    "--checkpoint_iterations",
    "{iterations}",
    "--use_nerual_phasefunc",
    "--eval",
    SUITE_ARGS,
)
_SSDGS_REAL_WINDOWS = ("--position_lr_max_steps", "70000", "--densify_until_iter", "90000")

SSDGS_CODE = OfficialCode(
    name="ssdgs-official",
    paper=(
        "SSD-GS: Scattering and Shadow Decomposition for Relightable 3D Gaussian Splatting (ICLR "
        "2026)"
    ),
    commands=(
        ("train", _SSDGS_TRAIN),
        (
            "render",
            (
                "render.py",
                "-m",
                "{model}",
                "--iteration",
                "{iterations}",
                "--skip_train",
                "--use_nerual_phasefunc",
                SUITE_ARGS,
            ),
        ),
    ),
    renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
    # render.py:70-71 reads the cameras train.py saved
    render_orders={"--opt_pose": _REFINED_CAMERAS},
    # its loader reads 8-bit RGBA PNGs (its GS³ and SSS-GS data are PNGs too)
    data_formats={ANY_SUITE: "nrhints"},
    suite_args={
        "gs3": {"train": ("--white_background", *_SSDGS_REAL_WINDOWS)},
        "nrhints": {
            "train": ("--cam_opt", "--pl_opt", *_SSDGS_REAL_WINDOWS),
            "render": ("--opt_pose",),
        },
        ANY_SUITE: {"train": ("--position_lr_max_steps", "50000", "--densify_until_iter", "50000")},
    },
    # render.py:80 torch.load()s its own checkpoint, which holds numpy scalars: torch >= 2.6's
    # weights_only default refuses it; this restores the default the code was written for (the file
    # is the job's own output).
    env={"OPENCV_IO_ENABLE_OPENEXR": "1", "TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD": "1"},
    schedule_flags=_SSDGS_SCHEDULE_FLAGS,
    point_cloud=_POINT_CLOUD,
    # arguments/__init__.py:54; render.py reads it back from the model's cfg_args
    # (get_combined_args, render.py:121)
    white_background_args=("--white_background",),
)

# ---- NRHints (iamNCJ/NRHints) --------------------------------------------------------------------
# One command: main.py trains to end_iter, then renders every test view into
# <base_dir>/<exp_name>/<scene_name>/test_views/step_<end_iter:07d>/rgb_<index:03d>.png.
NRHINTS_CODE = OfficialCode(
    name="nrhints-official",
    paper=(
        "NRHints: Relighting Neural Radiance Fields with Shadow and Highlight Hints (Zeng et al., "
        "SIGGRAPH 2023)"
    ),
    commands=(
        (
            "train",
            (
                "main.py",
                SUITE_ARGS,
                "--config.data.path",
                "{scene}",
                "--config.scene-name",
                "scene",
                "--config.base-dir",
                "{model}",
                "--config.exp-name",
                "olatbench",
                "--config.model.end-iter",
                "{iterations}",
            ),
        ),
    ),
    renders="{model}/olatbench/scene/test_views/step_{iterations:07d}/rgb_{index:03d}.png",
    data_formats={ANY_SUITE: "nrhints"},
    suite_args={  # the first argument is tyro's sub-command: it has to come first
        # train_real.sh passes --config.data.view-num-limit 1000, kept as the script has it; it has
        # no effect: trainer.py:116-123 never hands data.view_num_limit to the data manager, so
        # every training view is used
        "nrhints": {
            "train": (
                "config:nr-hints-cam-opt",
                "--config.data.white-background",
                "False",
                "--config.data.view-num-limit",
                "1000",
            )
        },
        "gs3": {"train": ("config:nr-hints", "--config.data.white-background", "True")},
        ANY_SUITE: {"train": ("config:nr-hints", "--config.data.white-background", "False")},
    },
    env={"WANDB_MODE": "offline"},  # it logs every run to wandb
    # what scripts/train_synthetic.sh passes for its white Blender scenes (the suite "gs3" above)
    white_background_args=("--config.data.white-background", "True"),
    needs_val_split=True,
    # data/data_parser.py:41-66 (top-level intrinsics, near/far of the first split)
    single_camera_model=True,
    scene_args=(
        SceneArgs(
            "nrhints",
            "Fish",
            "train",
            ("--config.model.geometry-warmup-end", "100000"),
            "scripts/train_real.sh:12",
        ),
    ),
)

# ---- RNG (sssssy/RNG_release) --------------------------------------------------------------------
# README.md:20-41 at 4e8748e: stage 1 (forward shading: a per-Gaussian colour MLP) for 30K steps,
# stage 2 (deferred shading with a shadow map and a depth MLP) from stage 1's checkpoint to 100K, in
# the same model folder; render.py with stage 2's pipeline flags. The stages' flags are the
# README's; olatbench names stage 1's length {stage1_iterations} (30000 at the README's 100K, scaled
# in shorter runs), saves only at the stages' ends (the README's extra --save_iteration 7000
# snapshot is read by nothing) and adds --skip_train to the render (the README renders the training
# views too, render.py:296-297).
_RNG_STAGE1 = (
    "--eval",
    "--json",
    "--color_mlp",
    "--in_channels",
    "16",
    "--max_training_images",
    "1000",
    "--max_reso",
    "512",
    "--loss",
    "l1",
)
_RNG_STAGE2_PIPE = (
    "--color_mlp",
    "--defer_shading",
    "--in_channels",
    "16",
    "--shadow_map",
    "--depth_mlp",
    "--depth_mlp_modifier",
    "1.0",
    "--encoding_levels_each",
    "2",
    "--encoding_levels_shadow",
    "8",
    "--max_reso",
    "512",
    "--crop_pc",
    "1.0",
)
# OptimizationParams (arguments/__init__.py:97-117): the iteration-valued ones. Not scaled:
# --densification_interval and --shadow_cache_rebuild (cadences), train.py:88's `iteration % 1000`
# SH step (no SH with --color_mlp) and train.py:192-201's fixed `iteration % 15000` learning-rate
# decay (x0.75; a constant of the script, not a flag: it never fires in a run shorter than 15000
# steps). --position_lr_max_steps is scaled but unused: train.py:85 has update_learning_rate
# commented out.
_RNG_SCHEDULE_FLAGS = {
    "--position_lr_max_steps": 30_000,
    "--densify_from_iter": 500,
    "--densify_until_iter": 15_000,
    "--opacity_reset_interval": 3_000,
}
_RNG_WHITE = "white"  # the variant preset that trains on a white background (docs/official.md)

RNG_CODE = OfficialCode(
    name="rng-official",
    paper="RNG: Relightable Neural Gaussians (Fan et al., CVPR 2025)",
    commands=(
        (
            "train",
            (
                "train.py",
                "-s",
                "{scene}",
                "-m",
                "{model}",
                "--iterations",
                "{stage1_iterations}",
                "--save_iterations",
                "{stage1_iterations}",
                "--densify_until_iter",
                "30000",
                *_RNG_STAGE1,
                SUITE_ARGS,
            ),
        ),
        (
            "train_stage2",
            (
                "train.py",
                "-s",
                "{scene}",
                "-m",
                "{model}",
                "--iterations",
                "{iterations}",
                "--save_iterations",
                "{iterations}",
                "--load_pc",
                "{model}/chkpnt{stage1_iterations}.pth",
                "--eval",
                "--json",
                "--loss",
                "l1",
                "--max_training_images",
                "1000",
                *_RNG_STAGE2_PIPE,
                "--shadow_grad",
                SUITE_ARGS,
            ),
        ),
        (
            "render",
            (
                "render.py",
                "-m",
                "{model}",
                "--iteration",
                "{iterations}",
                "--eval",
                "--json",
                *_RNG_STAGE2_PIPE,
                "--skip_train",
                SUITE_ARGS,
            ),
        ),
    ),
    # render_set (render.py:35-105) writes test view idx as <idx:05d>.png, iterating
    # scene.getTestCameras() of Scene(shuffle=False) (render.py:231); readCamerasFromTransforms
    # keeps transforms_test.json's order (scene/dataset_readers.py:222-233: --less 0 keeps every
    # frame; max_training_images is 0 for the test split, dataset_readers.py:304), so render i is
    # the i-th frame of the converted transforms_test.json.
    renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
    # render_set saves view idx's ground truth (original_image, the loader's composite) beside it
    # (render.py:42, 82)
    render_ground_truths="{model}/test/ours_{iterations}/gt/{index:05d}.png",
    # PIL reads file_path + file_ext (8-bit RGBA; dataset_readers.py:236-257)
    data_formats={ANY_SUITE: "nrhints"},
    # The paper (appendix, the commented paragraph at ssdgs_iclr2026.tex:535) says RNG kept its
    # original black background on the synthetic (GS³) scenes as well ("we did not retrain RNG ...
    # under this setting"): no suite passes --white_background
    # (default False, arguments/__init__.py:54); the variant preset `white` adds it.
    suite_args={},
    # train.py:46 torch.load()s its own stage-1 checkpoint
    env={"TORCH_FORCE_NO_WEIGHTS_ONLY_LOAD": "1"},
    schedule_flags=_RNG_SCHEDULE_FLAGS,
    # one camera_intrinsics / camera_angle_x per transforms file (dataset_readers.py:213)
    single_camera_model=True,
    train_steps=("train", "train_stage2"),
    milestones={"stage1_iterations": 30_000},
    # arguments/__init__.py:54 (the variant `white`); render.py reads it back from cfg_args
    # (render.py:335)
    white_background_args=("--white_background",),
    sources=(
        (
            "train (stage 1, forward shading)",
            "README.md:26 (python train.py ... --iterations 30000 --color_mlp)",
        ),
        (
            "train_stage2 (deferred shading)",
            "README.md:29 (--iterations 100000 --load_pc OUTPUT_PATH/chkpnt30000.pth "
            "--defer_shading --shadow_map --shadow_grad --depth_mlp ...)",
        ),
        ("render", "README.md:39 (render.py --iteration 100000 ... ; --skip_train added)"),
        (
            "the checkpoint stage 2 loads",
            "train.py:283-284 (checkpoint_iterations = save_iterations + [iterations]) "
            "and train.py:186 (<model>/chkpnt<it>.pth)",
        ),
        (
            "--in_channels 16",
            "the Gaussians' latent feature size fed to the colour MLP (arguments/__init__.py:75, "
            "gaussian_renderer/__init__.py:99); the same for every suite; the rasterizer is built "
            "for 16 channels (diff-gaussian-rasterization/cuda_rasterizer/config.h:15)",
        ),
        (
            "--max_training_images 1000",
            "a seeded random subset of at most 1000 training images "
            "(dataset_readers.py:225-233; np.random seeded 0 by safe_state): all of mini's "
            "100, of GS³'s 2000 synthetic images half",
        ),
        (
            "--max_reso 512",
            "halves an image whose height and width both exceed 512 (dataset_readers.py:258-260); "
            "mini's 80x80 images are kept; renders of halved images would not match the ground "
            "truth's size and the job fails saying so",
        ),
        (
            "background",
            "black on every benchmark suite: ssdgs_iclr2026.tex:535 (RNG kept its original black "
            "background on the synthetic data too); variant `white` adds --white_background "
            "(arguments/__init__.py:54); a scene of your own trains on the background its files "
            "declare",
        ),
        (
            "initial points",
            "not taken: readNerfSyntheticInfo always draws 100,000 random points in [-1.3, 1.3]^3 "
            "(dataset_readers.py:314-325, `if True:`) from np.random seeded 0 "
            "(utils/general_utils.py:133-135), so the job's seed changes nothing",
        ),
    ),
)

# ---- listed, not runnable ------------------------------------------------------------------------
_ENVMAP = (
    "its code relights with environment maps (HDR light probes) and has no point-light input, so "
    "olatbench's OLAT scenes (one point light per image) cannot be fed to it without changing the "
    "authors' code"
)

GIGS_CODE = OfficialCode(
    name="gigs-official",
    paper="GI-GS: Global Illumination Decomposition on Gaussian Splatting (Chen et al., ICLR 2025)",
    commands=(),
    renders="",
    unsupported=_ENVMAP,
)
TENSOIR_CODE = OfficialCode(
    name="tensoir-official",
    paper="TensoIR: Tensorial Inverse Rendering (Jin et al., CVPR 2023)",
    commands=(),
    renders="",
    unsupported=_ENVMAP,
)
R3DG_CODE = OfficialCode(
    name="r3dg-official",
    paper="Relightable 3D Gaussians: Real-time Point Cloud Relighting with BRDF Decomposition and "
    "Ray Tracing (Gao et al., ECCV 2024)",
    commands=(),
    renders="",
    unsupported=_ENVMAP,
)


def _spec(
    code_name: str,
    code: OfficialCode,
    description: str,
    source: SourcePin,
    presets: dict | None = None,
) -> MethodSpec:
    return MethodSpec(
        name=code.name,
        description=description,
        implementation=f"{_MODULE}:{code_name}",
        config=_CONFIG,
        kind="official",
        source=source,
        presets=presets or {},
        outputs=("rgb",),
        capabilities=frozenset({"relight"}),
    )


SPECS: tuple[MethodSpec, ...] = (
    _spec(
        "SSDGS_CODE",
        SSDGS_CODE,
        "SSD-GS, the authors' code (CUDA) run on olatbench's data",
        SourcePin(
            "irisfreesiri/SSD-GS",
            "26e42517e2c56cb2b943a18116560f292a06cd2c",
            "verified",
            "Commands are those of batch_script_{real_nrhints,synthetic_gs3,synthetic_sssgs}.py at "
            "this commit (+ --skip_train, --save/--checkpoint_iterations at the run's length), "
            "which give every scene of a suite the same flags (one command in a loop over "
            "scene_list, lines 67-126); variant opt adds --cam_opt --pl_opt / --opt_pose on "
            "SSS-GS (the paper's w/ Opt); every flag found in arguments/__init__.py and "
            "render.py; the loader reads transforms_{train,test}.json and file_path + '.png' "
            "(RGBA over the background); render.py writes test/ours_<it>/renders/<index:05d>.png "
            "in loader order. Read, not run on a GPU.",
        ),
        presets={
            "nrhints": {"iterations": 100_000},
            "gs3": {"iterations": 100_000},
            "sssgs": {"iterations": 60_000},
            "mini": {**_MINI, "preset_args": (*_MINI_SCHEDULE, "--maximum_gs", "5000")},
            # the paper's "Ours (w/ Opt)" on SSS-GS: the real-data script's refinement flags, which
            # batch_script_synthetic_sssgs.py does not pass (its runs are "Ours (w/o Opt)")
            "opt": {"train_args": ("--cam_opt", "--pl_opt"), "render_args": ("--opt_pose",)},
        },
    ),
    _spec(
        "GS3_CODE",
        GS3_CODE,
        "GS³, the authors' code (CUDA) run on olatbench's data",
        SourcePin(
            "gsrelight/gs-relight",
            "83c8daa41284cc310855dec6db3158106c065d11",
            "verified",
            "Commands are those of syn_train.sh / syn_render.sh (GS³ data: --hdr, EXR, --gamma) "
            "and real_train.sh (real data: --cam_opt --pl_opt) at this commit; every flag found "
            "in arguments/__init__.py and render.py; the loader reads "
            "transforms_{train,test}.json and file_path + '.exr' (--hdr) or '.png'; render.py "
            "writes test/ours_<it>/renders/<index:05d>.png in loader order, x^(1/2.2) with "
            "--gamma. Read, not run on a GPU.",
        ),
        presets={
            "nrhints": {"iterations": 100_000},
            "gs3": {"iterations": 100_000},
            "sssgs": {"iterations": 100_000},
            "mini": {**_MINI, "preset_args": (*_MINI_SCHEDULE, "--maximum_gs", "12000")},
        },
    ),
    _spec(
        "NRHINTS_CODE",
        NRHINTS_CODE,
        "NRHints (NeuS with shadow and highlight hints), the authors' code (CUDA)",
        SourcePin(
            "iamNCJ/NRHints",
            "291800d12c474d370ec85f99c4c1180c54b68e37",
            "verified",
            "Commands are those of scripts/train_{synthetic,real}.sh at this commit (tyro "
            "sub-commands config:nr-hints / config:nr-hints-cam-opt; --config.model.end-iter, "
            "base-dir, exp-name, scene-name found in configs/main_config.py and "
            "models/neus_hint_model.py); the loader reads transforms_{train,val,test}.json and "
            "file_path + '.png'; after training trainer.py writes every test view to "
            "<base>/<exp>/<scene>/test_views/step_<it:07d>/rgb_<i:03d>.png (with camera "
            "optimisation it first fits each test view's pose for 500 steps). Read, not run.",
        ),
        presets={
            "nrhints": {"iterations": 1_000_000},
            "gs3": {"iterations": 1_000_000},
            "sssgs": {"iterations": 1_000_000},
        },
    ),
    _spec(
        "RNG_CODE",
        RNG_CODE,
        "RNG (Relightable Neural Gaussians), the authors' code (CUDA): two stages",
        SourcePin(
            "sssssy/RNG_release",
            "4e8748e1cc9915b1c9d67538d2ec46dc59c0d7f4",
            "verified",
            "Commands are the README's (README.md:20-41) at this commit: stage 1 forward shading, "
            "stage 2 deferred shading from stage 1's checkpoint, render.py; every flag found in "
            "arguments/__init__.py and train.py / render.py; the loader (--json) reads "
            "transforms_{train,test}.json and file_path + file_ext with PIL (RGBA over the "
            "background); render.py writes test/ours_<it>/renders/<index:05d>.png in loader "
            "order. Read, and run on the CPU with the stand-ins (docs/official.md); not run on a "
            "GPU.",
        ),
        presets={
            "nrhints": {"iterations": 100_000},
            "gs3": {"iterations": 100_000},
            "sssgs": {"iterations": 100_000},
            "mini": {"iterations": 3_000, "reference_iterations": 100_000},
            _RNG_WHITE: {"train_args": ("--white_background",)},
        },
    ),
    _spec(
        "GIGS_CODE",
        GIGS_CODE,
        "GI-GS: environment-map relighting only, cannot take OLAT data",
        SourcePin(
            "stopaimme/GI-GS-official-implementation",
            "9e75c82674726178e955dd3e6c4aca165cba9b31",
            "verified",
            "Read at this commit: relight.py takes --hdri (an environment map); no point-light "
            "position is read anywhere (no pl_pos / point light in the code).",
        ),
    ),
    _spec(
        "TENSOIR_CODE",
        TENSOIR_CODE,
        "TensoIR: environment-map relighting only, cannot take OLAT data",
        SourcePin(
            "Haian-Jin/TensoIR",
            "8f7b8dd87b5960847264536bb969c93dadeac1b5",
            "verified",
            "Read at this commit: the data loaders read HDR environment maps (light_name_list, "
            "hdr_dir); no point-light input exists.",
        ),
    ),
    _spec(
        "R3DG_CODE",
        R3DG_CODE,
        "Relightable 3D Gaussians: environment-map relighting only, cannot take OLAT data",
        SourcePin(
            "NJU-3DV/Relightable3DGaussian",
            "a102f14c7e34b7bd5e421990e6f1593d39ebab83",
            "verified",
            "Read at this commit: relighting evaluation takes --envmap_path (scene/envmap.py "
            "EnvLight); no point-light input exists.",
        ),
    ),
)
