"""Named SSD-GS presets; a variant composes several (``"mini+ablation-C"``) left to right
(`olatbench.methods.resolve`).

Suite presets set the run length, background and refinement of the paper's settings; ablation
presets only switch terms (Composition A-F), schedule presets only pick the schedule (H-K), so a
suite preset combines with one of each.
"""

from __future__ import annotations

from typing import Any

from olatbench.methods.authors import OFFICIAL_VARIANT
from olatbench.methods.ssdgs.authors import AUTHORS

# The official code's behaviour where it departs from the paper's equations (docs/ssdgs.md, "Where
# the paper and the official code differ"): the paper's numbers were produced by that code, so the
# suite presets follow it; the config defaults keep the paper's choices. Values read from
# irisfreesiri/SSD-GS (train.py, arguments/, scene/, gaussian_renderer/, the light rasterizer's
# forward.cu).
OFFICIAL_CODE: dict[str, Any] = {
    # local_q (identity at start), used unflipped
    "shading_frame": "learned",
    "orient_normals": False,
    # angular ASG; only asg_scales/asg_rotation frozen
    "asg_form": "official",
    "asg_freeze_sigma": False,
    "dipole_virtual_factor": "official",  # z_r·z_v
    # out_trans / non_trans, dd < 4 (2 px), offset
    "shadow_mode": "density",
    "shadow_depth_offset": 0.015,
    "shadow_freqs": 4,  # phasefunc_frequency
    # uniform in [-0.5, 0.5]³
    "num_init_gaussians": 100_000,
    "init_shape": "box",
    "init_radius": 1.0,
    "refine_camera_from": 5_000,
    "refine_light_from": 15_000,
    "refinement_lr_clock": "absolute",
    "camera_lr_delay_steps": 20_000,
    "camera_lr_delay_mult": 0.2,  # opt_cam_lr_* (max 80K)
    "light_lr_delay_steps": 30_000,
    "light_lr_delay_mult": 0.1,  # opt_pl_lr_* (max 80K)
    # prune_visibility / is_train
    "densify_before_update": True,
    "light_weight_accumulation": "near_cap",
}

SUITE_PRESETS: dict[str, dict[str, Any]] = {
    # NRHints real captures: 100K iterations, black background, camera and light refinement, test
    # views' poses and lights fitted during training (the official real-data protocol).
    "nrhints": {
        **OFFICIAL_CODE,
        "iterations": 100_000,
        "reference_iterations": 100_000,
        "background": (0.0, 0.0, 0.0),
        "refine_camera": True,
        "refine_light": True,
        "test_pose_fitting": "interleaved",
        "position_lr_max_steps": 70_000,
        "densify_until": 90_000,
    },
    # GS³ synthetic: 100K iterations, white background, known poses and lights.
    "gs3": {
        **OFFICIAL_CODE,
        "iterations": 100_000,
        "reference_iterations": 100_000,
        "background": (1.0, 1.0, 1.0),
        "refine_camera": False,
        "refine_light": False,
        "position_lr_max_steps": 70_000,
        "densify_until": 90_000,
    },
    # SSS-GS synthetic at 256²: 60K iterations with the same absolute phase thresholds as the 100K
    # runs (the official script), black background; "w/ Opt" refines cameras and lights, and then
    # (as the code does whenever it refines) fits the test views' too.
    "sssgs": {
        **OFFICIAL_CODE,
        "iterations": 60_000,
        "reference_iterations": 60_000,
        "background": (0.0, 0.0, 0.0),
        "refine_camera": True,
        "refine_light": True,
        "test_pose_fitting": "interleaved",
        "position_lr_max_steps": 50_000,
        "densify_until": 50_000,
    },
    "sssgs-no-opt": {
        **OFFICIAL_CODE,
        "iterations": 60_000,
        "reference_iterations": 60_000,
        "background": (0.0, 0.0, 0.0),
        "refine_camera": False,
        "refine_light": False,
        "position_lr_max_steps": 50_000,
        "densify_until": 50_000,
    },
    # CPU-sized: the 60K schedule compressed 20× into 3000 steps, few Gaussians, small light-view
    # pass. Values below that are iteration counts are at the 60K reference (× 0.05 at run time).
    # Two changes measured on the mini scenes (docs/ssdgs.md): the networks get 20× fewer Adam steps
    # than in a 60K run, so their rate is 5× the paper's; and the light-view pass excludes occluders
    # within 1.8 squared-distance units (≈ 0.2 scene units at the mini lights' ≈ 4.5) of each
    # Gaussian, because the few, wide Gaussians of a short run otherwise shadow their own surface
    # ("acne": mean visibility ≈ 0.1). Both were tuned with the light view fitted to the scene,
    # which mini keeps (0.2-0.6 dB better there than the official camera-matched framing). Of the
    # official code's switches mini takes only the learned shading frame, the one that trained
    # better at 3000 steps (+1.3 dB over 3 seeds x 3 scenes; docs/ssdgs.md).
    "mini": {
        "iterations": 3_000,
        "reference_iterations": 60_000,
        "background": None,
        "shading_frame": "learned",
        "orient_normals": False,
        "num_init_gaussians": 2_000,
        "init_radius": None,
        "max_gaussians": 5_000,
        "shadow_resolution": 96,
        "shadow_framing": "scene",
        "shadow_depth_offset": 1.8,
        "mlp_lr_init": 5e-3,
        "mlp_lr_final": 5e-5,
        "sss_hidden": 64,
        "num_asg": 4,
        "position_lr_max_steps": 60_000,
        "densify_from": 4_000,
        "densify_until": 44_000,
        "densify_interval": 100,
        "densify_grad_threshold": 2e-4,
        "opacity_reset_interval": 30_000,
        "asg_lr_decay_from": 40_000,
        "asg_lr_max_steps": 20_000,
        "mlp_lr_decay_from": 40_000,
        "mlp_lr_max_steps": 20_000,
        "refine_camera": False,
        "refine_light": False,
        "test_pose_fitting": "none",
    },
}

# Scenes of one's own (`MethodSpec.scene_recipe`, scaled to each scene by
# olatbench.methods.scene_presets): the mini recipe over the official code's switches (box init,
# density shadows with 4 frequencies, the angular ASG, the official dipole factor, density control
# before the Adam update, light weights near the budget; refinement stays off) - what `--variant
# mini` gave on a scene of one's own before presets were derived from the scene. Measured on a 64²
# scene of 30 training views (docs/own-data.md): 12.92 ± 0.28 dB with the mini recipe alone
# (3 seeds), 14.59 ± 0.38 with these switches (10 seeds); the mini scenes keep the mini preset,
# measured better without them there.
SUITE_PRESETS["own-data"] = {**OFFICIAL_CODE, **SUITE_PRESETS["mini"]}

ABLATION_PRESETS: dict[str, dict[str, Any]] = {
    "ablation-A": {"use_specular": False, "use_sss": False, "use_shadow": False},  # diffuse only
    "ablation-B": {"use_specular": True, "use_sss": False, "use_shadow": False},  # + specular
    "ablation-C": {"use_specular": True, "use_sss": True, "use_shadow": False},  # + SSS
    "ablation-D": {"use_specular": True, "use_sss": True, "use_shadow": True},  # full model
    "ablation-E": {"use_specular": False, "use_sss": True, "use_shadow": True},  # full - specular
    "ablation-F": {"use_specular": True, "use_sss": False, "use_shadow": True},  # full - SSS
    "shadow-on-sss": {"shadow_on_sss": True},
}

SCHEDULE_PRESETS: dict[str, dict[str, Any]] = {
    f"schedule-{name}": {"schedule": name} for name in "HIJK"
}

# Evaluation options: fit each test view's pose/light to its image before scoring
# (recorded in results.json). Combine with a suite that refines cameras/lights, e.g. --variant
# test-time-refinement on nrhints.
EVALUATION_PRESETS: dict[str, dict[str, Any]] = {
    "test-time-refinement": {"test_time_refinement": True}
}

# The authors' code on any suite and length (`olatbench.methods.ssdgs.authors`): every field with a
# counterpart in their code takes their value, over the suite preset's run settings
# (`--variant official`).
PARITY_PRESETS: dict[str, dict[str, Any]] = {OFFICIAL_VARIANT: AUTHORS.preset()}

PRESETS: dict[str, dict[str, Any]] = {
    **SUITE_PRESETS,
    **ABLATION_PRESETS,
    **SCHEDULE_PRESETS,
    **EVALUATION_PRESETS,
    **PARITY_PRESETS,
}
