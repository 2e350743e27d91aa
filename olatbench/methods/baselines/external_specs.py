"""Specs of official implementations that `olatbench.methods.baselines.external` can run, as data.

A spec says where the code lives (repository URL and a pinned commit, ``"unverified"`` where the commit could
not be checked from here), in which olatbench format its scene must be written (`convert.write_scene`), the
command lines of its train and render scripts, and where the renders land and how they are named.

Command lines are argument lists. Placeholders (`str.format` fields) are replaced per run:

- ``{python}`` the interpreter of the official environment, ``{checkout}`` the user's clone,
- ``{scene}`` the converted scene folder, ``{model}`` the output folder the scripts write to,
- ``{iterations}`` the training length;
- an argument that is exactly ``{*suite_args}`` expands into the spec's extra arguments for the suite and
  step (``suite_args[suite][step]``, e.g. ``--white_background`` for GS³ data), possibly none.

``renders`` is a pattern relative to nothing (placeholders as above plus ``{index}`` — the frame's position in
the written split, which is the order the official loaders read — and ``{stem}`` — its file stem).
"""

from __future__ import annotations

from dataclasses import dataclass, field

UNVERIFIED = "unverified"


@dataclass(frozen=True)
class ExternalSpec:
    """How to run one official implementation as a separate process (see the module docstring)."""

    name: str
    paper: str
    repository: str
    commit: str  # 40 hex digits, or UNVERIFIED
    data_format: str  # olatbench format the scene is written in: "nrhints", "gs3" or "sssgs"
    commands: tuple[tuple[str, tuple[str, ...]], ...]  # (step name, argv) in order
    renders: str  # path pattern of one test render
    render_colourspace: dict[str, str] = field(default_factory=dict)  # suite -> what the PNGs hold (default srgb)
    suite_args: dict[str, dict[str, tuple[str, ...]]] = field(default_factory=dict)  # suite -> step -> args
    env: dict[str, str] = field(default_factory=dict)
    notes: str = ""

    def colourspace_for(self, suite: str | None) -> str:
        """The colour space of the renders for ``suite`` ("srgb" unless the spec says otherwise)."""
        return self.render_colourspace.get(suite or "", "srgb")

    def args_for(self, suite: str | None, step: str) -> tuple[str, ...]:
        """The suite's extra arguments for ``step`` (what ``{*suite_args}`` expands to)."""
        return self.suite_args.get(suite or "", {}).get(step, ())

    def __post_init__(self) -> None:
        if self.commit != UNVERIFIED and (len(self.commit) != 40 or any(c not in "0123456789abcdef"
                                                                        for c in self.commit)):
            raise ValueError(f"external spec {self.name!r}: commit must be 40 lowercase hex digits or "
                             f"{UNVERIFIED!r}, got {self.commit!r}")
        if not self.commands:
            raise ValueError(f"external spec {self.name!r}: no commands")


_GS3_TRAIN_FLAGS = (
    "--iterations", "{iterations}", "--use_nerual_phasefunc", "--eval", "--view_num", "2000",
    "--asg_freeze_step", "22000", "--spcular_freeze_step", "9000", "--fit_linear_step", "7000",
    "--asg_lr_freeze_step", "40000", "--asg_lr_max_steps", "50000", "--asg_lr_init", "0.01",
    "--asg_lr_final", "0.0001", "--local_q_lr_freeze_step", "40000", "--local_q_lr_init", "0.01",
    "--local_q_lr_final", "0.0001", "--local_q_lr_max_steps", "50000", "--neural_phasefunc_lr_init", "0.001",
    "--neural_phasefunc_lr_final", "0.00001", "--freeze_phasefunc_steps", "50000",
    "--neural_phasefunc_lr_max_steps", "50000", "--position_lr_max_steps", "50000", "--densify_until_iter", "50000",
    "--unfreeze_iterations", "5000", "--save_iterations", "{iterations}", "--checkpoint_iterations", "{iterations}",
)

SPECS: dict[str, ExternalSpec] = {
    "gs3": ExternalSpec(
        name="gs3", paper="GS³: Efficient Relighting with Triple Gaussian Splatting (SIGGRAPH Asia 2024)",
        repository="https://github.com/gsrelight/gs-relight",
        commit="4b50c84b7f7c1e15712a7f243222409f0c7b35e9",
        data_format="gs3",
        commands=(
            ("train", ("{python}", "train.py", "-s", "{scene}", "-m", "{model}", *_GS3_TRAIN_FLAGS, "{*suite_args}")),
            ("render", ("{python}", "render.py", "-m", "{model}", "--iteration", "{iterations}", "--skip_train",
                        "--use_nerual_phasefunc", "{*suite_args}")),
        ),
        renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
        render_colourspace={"gs3": "gamma22"},
        suite_args={"gs3": {"train": ("--hdr", "--white_background"), "render": ("--gamma",)},
                    "nrhints": {"train": ("--cam_opt", "--pl_opt")}},
        notes="Flags of the official syn_train.sh / syn_render.sh (commit seen in a public index of the repository, "
              "not checked against GitHub; the Drums and "
              "Lego scenes use other freeze steps there). render.py writes test views in loader order as "
              "<index:05d>.png; --gamma stores x^(1/2.2).",
    ),
    "ssdgs": ExternalSpec(
        name="ssdgs", paper="SSD-GS (ICLR 2026)",
        repository="https://github.com/irisfreesiri/SSD-GS",
        commit="c7025c06486407103644d9bd39421ebffa85cf37",
        data_format="nrhints",
        commands=(
            ("train", ("{python}", "train.py", "-s", "{scene}", "-m", "{model}", "--data_device", "cpu",
                       "--view_num", "2000", "--iterations", "{iterations}", "--asg_freeze_step", "22000",
                       "--specular_freeze_step", "9000", "--fit_linear_step", "7000", "--asg_lr_freeze_step", "40000",
                       "--asg_lr_max_steps", "50000", "--asg_lr_init", "0.01", "--asg_lr_final", "0.0001",
                       "--local_q_lr_freeze_step", "40000", "--local_q_lr_init", "0.01", "--local_q_lr_final",
                       "0.0001", "--local_q_lr_max_steps", "50000", "--neural_phasefunc_lr_init", "0.001",
                       "--neural_phasefunc_lr_final", "0.00001", "--freeze_phasefunc_steps", "50000",
                       "--neural_phasefunc_lr_max_steps", "50000", "--position_lr_max_steps", "70000",
                       "--densify_until_iter", "90000", "--unfreeze_iterations", "5000",
                       "--save_iterations", "{iterations}", "--checkpoint_iterations", "{iterations}",
                       "--use_nerual_phasefunc", "--eval", "{*suite_args}")),
            ("render", ("{python}", "render.py", "-m", "{model}", "--iteration", "{iterations}", "--skip_train",
                        "--use_nerual_phasefunc", "{*suite_args}")),
        ),
        renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
        suite_args={"gs3": {"train": ("--white_background",)},
                    "nrhints": {"train": ("--cam_opt", "--pl_opt"), "render": ("--opt_pose",)}},
        env={"OPENCV_IO_ENABLE_OPENEXR": "1"},
        notes="Flags of batch_script_real_nrhints.py / batch_script_synthetic_gs3.py (commit seen in the public "
              "index, not checked against GitHub); real data trains with camera/light refinement and renders "
              "with the refined poses.",
    ),
    "rng": ExternalSpec(
        name="rng", paper="RNG: Relightable Neural Gaussians (Fan et al. 2025)",
        repository="https://github.com/whois-jiahui/RNG",
        commit=UNVERIFIED,
        data_format="nrhints",
        commands=(
            ("train", ("{python}", "train.py", "-s", "{scene}", "-m", "{model}", "--iterations", "{iterations}",
                       "--eval", "{*suite_args}")),
            ("render", ("{python}", "render.py", "-m", "{model}", "--iteration", "{iterations}", "--skip_train")),
        ),
        renders="{model}/test/ours_{iterations}/renders/{index:05d}.png",
        suite_args={"gs3": {"train": ("--white_background",)}},
        notes="UNVERIFIED: repository URL, commit, flags and output layout were not checkable from here; they "
              "assume the 3DGS script conventions RNG builds on. Check them against the checkout before use.",
    ),
    "gigs": ExternalSpec(
        name="gigs", paper="GI-GS: Global Illumination Decomposition on Gaussian Splatting (ICLR 2025)",
        repository="https://github.com/stopaimme/GI-GS-official-implementation",
        commit=UNVERIFIED,
        data_format="nrhints",
        commands=(
            ("train", ("{python}", "train.py", "-s", "{scene}", "-m", "{model}", "--iterations", "{iterations}",
                       "--eval", "{*suite_args}")),
            ("render", ("{python}", "render.py", "-m", "{model}", "--checkpoint",
                        "{model}/chkpnt{iterations}.pth", "--skip_train", "--pbr")),
        ),
        renders="{model}/test/ours_{iterations}/pbr/{index:05d}.png",
        suite_args={"gs3": {"train": ("--white_background",)}},
        notes="UNVERIFIED: the training command (GI-GS trains in stages) and the commit are guesses; render.py "
              "writes the final PBR image of test view i as pbr/<i:05d>.png (seen in the public index). GI-GS "
              "ignores the OLAT light (environment-map relighting).",
    ),
}


def get_spec(name: str) -> ExternalSpec:
    """The spec registered as ``name``; a `KeyError` listing the known ones otherwise."""
    if name not in SPECS:
        raise KeyError(f"no external spec {name!r}; known: {', '.join(sorted(SPECS))}")
    return SPECS[name]


__all__ = ["SPECS", "UNVERIFIED", "ExternalSpec", "get_spec"]
