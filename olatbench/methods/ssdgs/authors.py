"""SSD-GS as the authors' code has it (irisfreesiri/SSD-GS at 26e4251, read for each line cited),
and why the native presets depart from it: the data of ``--variant official`` and ``olatbench
methods diff ssdgs`` (`olatbench.methods.authors`). Paths are in that repository; iteration counts
are at the scripts' lengths and scale with a run's length as the official runner scales the
flags."""

from __future__ import annotations

from olatbench.methods.authors import (
    RUNNER_SUITE_FIELDS,
    AuthorsConfig,
    AuthorsValue,
    Departure,
    Unswitchable,
)

_ARGS = "arguments/__init__.py"
_RENDER = "gaussian_renderer/__init__.py"
_SWITCHES = "docs/ssdgs.md, 'The official-code switches on mini' (3 seeds × 3 scenes, 2026-11-25)"
_MINI_WHY = "docs/ssdgs.md, 'Why mini departs' (one seed per scene, before 2026-11-22)"
_NOT_MEASURED = "not measured on its own"
_COST = (
    "docs/official.md, 'What the mini preset's departures cost' (aniso_metal, "
    "light_intensity=ignored, 3 seeds, 2026-11-28)"
)


def _group(fields: str, delta: str, noise: str) -> str:
    """The measured effect of setting ``fields`` to the authors' values together on the mini preset
    under ``light_intensity=ignored`` (``delta`` in dB, ``noise``: "within" or "beyond")."""
    return f"the authors' {fields} on mini: {delta} dB on aniso_metal, {noise} seed noise ({_COST})"


_LOBES = _group("lobes (asg_form, asg_freeze_sigma, num_asg, asg_lr_max_steps)", "+2.39", "beyond")
_LIGHT_VIEW = _group(
    "light view (shadow_resolution, shadow_depth_offset, shadow_framing, shadow_mode, "
    "shadow_freqs)",
    "-0.56",
    "beyond",
)
_RATES = _group(
    "network rates (mlp_lr_init, mlp_lr_final, mlp_lr_decay_from, mlp_lr_max_steps)",
    "+1.64",
    "beyond",
)
_SSS = _group("SSS network (sss_hidden, sss_layers, sss_last_hidden)", "-0.32", "within")


VALUES: dict[str, AuthorsValue] = {
    "schedule": AuthorsValue(
        "I",
        "train.py:96-225",
        "phase flags --specular_freeze_step 9000, --fit_linear_step "
        "7000, --scatter_* (arguments/__init__.py:104-114), passed by the batch scripts",
    ),
    "schedule_counting": AuthorsValue(
        "official",
        "train.py:131-133",
        "iteration counted from 1; SSS and specular on at iteration = threshold "
        "(`iteration < ...`), shadow after it (`iteration <= ...`)",
    ),
    "use_shadow": AuthorsValue(True, "train.py:131-136"),
    "use_sss": AuthorsValue(True, "train.py:131-136"),
    "use_specular": AuthorsValue(True, "train.py:131-136"),
    "diffuse_cosine": AuthorsValue(
        "smooth", f"{_RENDER}:159,272-279", "ELU(alpha=0.01) smooth clamp"
    ),
    "shading_frame": AuthorsValue(
        "learned", "scene/gaussian_model.py:278-281", "local_q, identity at start"
    ),
    "orient_normals": AuthorsValue(False, f"{_RENDER}:169", "local z used as it is"),
    "num_asg": AuthorsValue(8, f"{_ARGS}:69", "basis_asg_num; no script passes --basis_asg_num"),
    "asg_form": AuthorsValue(
        "official", "scene/mixture_ASG.py:14,78-79", "exp(-½(θ·a/σ)²) / (√2·π^(2/3)·σ)"
    ),
    "asg_freeze_sigma": AuthorsValue(
        False,
        "train.py:96-102, scene/mixture_ASG.py:21",
        "only asg_scales and asg_rotation are frozen; σ trains once specular is on",
    ),
    "fresnel_f0": AuthorsValue(0.04, "scene/mixture_ASG.py:15"),
    "material_dim": AuthorsValue(6, f"{_ARGS}:67"),
    "shadow_hidden": AuthorsValue(32, f"{_ARGS}:62"),
    "shadow_layers": AuthorsValue(3, f"{_ARGS}:63"),
    "shadow_freqs": AuthorsValue(4, f"{_ARGS}:65", "phasefunc_frequency"),
    "shadow_input_bias": AuthorsValue(
        "padded_ones",
        "scene/neural_phase_function.py:34",
        "tcnn.Network: FullyFusedMLP pads the input with ones to a multiple of 16 "
        "(9 columns here), no biases",
    ),
    "sss_hidden": AuthorsValue(256, "scene/scatter_mlp.py:14-23"),
    "sss_layers": AuthorsValue(5, "scene/scatter_mlp.py:14-23", "5 Linear layers"),
    "sss_last_hidden": AuthorsValue(
        128, "scene/scatter_mlp.py:20-22", "the last hidden layer is 128 wide"
    ),
    "sss_freqs": AuthorsValue(4, f"{_RENDER}:170-171"),
    "dipole_eta": AuthorsValue(1.3, "scene/scatter_mlp.py:54"),
    "dipole_virtual_factor": AuthorsValue(
        "official", "scene/scatter_mlp.py:84", "term_v = zr * zv * ..."
    ),
    "shadow_mode": AuthorsValue(
        "density", f"{_RENDER}:132-134", "non_trans weights, thres = 4 (2 px)"
    ),
    "shadow_depth_offset": AuthorsValue(0.015, f"{_RENDER}:133"),
    "shadow_framing": AuthorsValue(
        "camera", f"{_RENDER}:50-68", "the viewing camera's focal × |light| / |camera|"
    ),
    "shadow_resolution": AuthorsValue(None, f"{_RENDER}:83-84", "the viewing camera's image size"),
    "init_opacity": AuthorsValue(0.1, "scene/gaussian_model.py:259"),
    "lambda_dssim": AuthorsValue(0.2, f"{_ARGS}:146"),
    "position_lr_init": AuthorsValue(1.6e-4, f"{_ARGS}:93"),
    "position_lr_final": AuthorsValue(1.6e-6, f"{_ARGS}:94"),
    "position_lr_delay_mult": AuthorsValue(0.01, f"{_ARGS}:95"),
    "scaling_lr": AuthorsValue(5e-3, f"{_ARGS}:143"),
    "rotation_lr": AuthorsValue(1e-3, f"{_ARGS}:144"),
    "opacity_lr": AuthorsValue(0.05, f"{_ARGS}:142"),
    "percent_dense": AuthorsValue(0.01, f"{_ARGS}:145"),
    "densify_interval": AuthorsValue(100, f"{_ARGS}:147"),
    "densify_grad_threshold": AuthorsValue(2e-4, f"{_ARGS}:151"),
    "colour_lr": AuthorsValue(0.01, f"{_ARGS}:99-102", "kd_lr, ks_lr, ksss_lr"),
    "asg_lr_init": AuthorsValue(0.01, f"{_ARGS}:123"),
    "asg_lr_final": AuthorsValue(1e-4, f"{_ARGS}:124"),
    "asg_lr_decay_from": AuthorsValue(
        40_000, f"{_ARGS}:122, scene/gaussian_model.py:359", "asg_lr_freeze_step"
    ),
    "asg_lr_max_steps": AuthorsValue(50_000, f"{_ARGS}:126"),
    "mlp_lr_init": AuthorsValue(
        1e-3, f"{_ARGS}:116,137", "scatter_lr_init, neural_phasefunc_lr_init"
    ),
    "mlp_lr_final": AuthorsValue(1e-5, f"{_ARGS}:117,138"),
    "mlp_lr_decay_from": AuthorsValue(
        50_000, f"{_ARGS}:115,136", "scatter_lr_freeze_step, freeze_phasefunc_steps"
    ),
    "mlp_lr_max_steps": AuthorsValue(50_000, f"{_ARGS}:119,140"),
    "camera_lr_init": AuthorsValue(1e-3, f"{_ARGS}:156"),
    "camera_lr_final": AuthorsValue(1e-5, f"{_ARGS}:157"),
    "light_lr_init": AuthorsValue(1e-3, f"{_ARGS}:163"),
    "light_lr_final": AuthorsValue(5e-5, f"{_ARGS}:164"),
    "refinement_lr_max_steps": AuthorsValue(80_000, f"{_ARGS}:160,167"),
    "refine_camera_from": AuthorsValue(5_000, f"{_ARGS}:155", "train_cam_freeze_step"),
    "refine_light_from": AuthorsValue(15_000, f"{_ARGS}:162", "train_pl_freeze_step"),
    "refinement_lr_clock": AuthorsValue(
        "absolute", "scene/__init__.py:103-106", "the decay at the absolute iteration"
    ),
    "camera_lr_delay_steps": AuthorsValue(20_000, f"{_ARGS}:158"),
    "camera_lr_delay_mult": AuthorsValue(0.2, f"{_ARGS}:159"),
    "light_lr_delay_steps": AuthorsValue(30_000, f"{_ARGS}:165"),
    "light_lr_delay_mult": AuthorsValue(0.1, f"{_ARGS}:166"),
    "densify_before_update": AuthorsValue(
        True, "train.py:185-199", "densify_and_prune before optimizer.step()"
    ),
    "light_weight_accumulation": AuthorsValue(
        "near_cap", "train.py:134,188-194", "is_train = prune_visibility"
    ),
    "light_intensity": AuthorsValue(
        "ignored",
        "scene/cameras.py:20, scene/dataset_readers.py:183",
        "pl_intensity is read and handed to the camera, which never uses it",
    ),
}

#: Set by the suite for both runners: the official runner passes the same run length, initial
#: points, budget, density window and background on a suite as the native suite preset
#: (olatbench.methods.official.specs).
SUITE_FIELDS = RUNNER_SUITE_FIELDS | {
    "background",
    "refine_camera",
    "refine_light",
    "test_pose_fitting",
}

_PAPER = (
    "the paper's choice, kept as the config's default (docs/ssdgs.md, 'Where the paper and the "
    "official code "
)
_INERT = (
    "inert while refine_camera and refine_light are off (every suite without refinement, mini "
    "included)"
)

DEPARTURES: dict[str, dict[str, Departure]] = {
    "default": {
        "shading_frame": Departure(
            _PAPER + "differ': the smallest-scale axis)",
            f"the learned frame +1.31 dB on average on mini ({_SWITCHES}); mini takes it",
        ),
        "orient_normals": Departure(_PAPER + "differ')", "measured with shading_frame, above"),
        "asg_form": Departure(
            _PAPER + "differ': Xu et al.'s ASG, peak fixed at 1)",
            f"-0.02 dB on average, -0.20 on aniso_metal with asg_freeze_sigma=false ({_SWITCHES}); "
            + _LOBES,
        ),
        "asg_freeze_sigma": Departure(
            _PAPER + "differ': every lobe parameter held in the freeze)",
            "measured with asg_form, above",
        ),
        "shadow_freqs": Departure(
            _PAPER + "differ': L = 3)",
            f"-0.30 dB on average, within seed noise ({_SWITCHES}); " + _LIGHT_VIEW,
        ),
        "schedule_counting": Departure(
            "the schedule's thresholds read as 0-based steps for every term (the paper's "
            "9K and 16K)",
            "SSS and specular one step later; below the parity "
            "harness's resolution in its first 100 steps (docs/official.md, "
            "'Step-by-step parity'); "
            + _group("schedule_counting and shadow_input_bias", "+0.06", "within"),
        ),
        "shadow_input_bias": Departure(
            "a plain MLP's bias vector (the paper describes the network, not "
            "tiny-cuda-nn's layout); the function is the same, Adam's steps on the bias "
            "are up to 9× smaller",
            "first cause of the step-by-step parity harness's loss "
            "difference once the shadow term is on (docs/official.md, 'Step-by-step "
            "parity'); measured with schedule_counting, above",
        ),
        "sss_layers": Departure(
            _PAPER + "differ': 6 layers × 256)",
            _SSS,
        ),
        "sss_last_hidden": Departure(
            _PAPER + "differ': every hidden layer sss_hidden wide)", "measured with sss_layers"
        ),
        "dipole_virtual_factor": Departure(
            _PAPER + "differ': Jensen's z_v; z_r·z_v is dimensionally inconsistent)",
            f"-0.10 dB on translucent with the learned frame, within noise ({_SWITCHES}); "
            + _group("dipole factor", "-0.26", "within"),
        ),
        "shadow_mode": Departure(
            _PAPER + "differ': Eq. 6 over the footprint; uniform is the fast C++ pass)",
            f"-0.04 dB on average, -1.1 on translucent, 43 % slower ({_SWITCHES}); " + _LIGHT_VIEW,
        ),
        "shadow_depth_offset": Departure(_PAPER + "differ': no offset)", _NOT_MEASURED),
        "refine_camera_from": Departure("our reading of the paper: with the shadow phase", _INERT),
        "refine_light_from": Departure("our reading of the paper: with the specular phase", _INERT),
        "refinement_lr_clock": Departure("our reading: the decay counted from the start", _INERT),
        "camera_lr_delay_steps": Departure("the paper states no warm-up", _INERT),
        "camera_lr_delay_mult": Departure("the paper states no warm-up", _INERT),
        "light_lr_delay_steps": Departure("the paper states no warm-up", _INERT),
        "light_lr_delay_mult": Departure("the paper states no warm-up", _INERT),
        "densify_before_update": Departure(
            "3DGS's order (update, then densify); the paper says nothing",
            _group("densify_before_update and light_weight_accumulation", "-0.04", "within"),
        ),
        "light_weight_accumulation": Departure(
            "the cap's priority is kept current; the paper says nothing",
            "measured with densify_before_update, above",
        ),
        "light_intensity": Departure(
            "olatbench's convention: a point light's recorded intensity multiplies its irradiance",
            "mini, 3 seeds: aniso_metal 19.03 ± 0.36 dB recorded, 14.73 ± "
            "0.39 ignored (docs/official.md, 'Measured')",
        ),
    },
    "mini": {
        "num_asg": Departure(
            "CPU budget: half the lobes",
            _LOBES,
        ),
        "sss_hidden": Departure(
            "CPU budget: a 64-wide SSS network",
            _SSS,
        ),
        "shadow_resolution": Departure(
            "CPU budget: a 96² light view",
            _LIGHT_VIEW,
        ),
        "shadow_framing": Departure(
            "tuned with the light view fitted to the scene",
            f"camera framing 0.2-0.6 dB lower, one seed ({_MINI_WHY}); the light-view "
            "group: see shadow_resolution",
        ),
        "shadow_depth_offset": Departure(
            "the few, wide Gaussians of a short run shadow their own surface with the "
            "official 0.015 (acne: mean visibility ≈ 0.1)",
            f"with mlp_lr_init 5e-3: +2.5 to +2.9 dB on the three scenes, one seed "
            f"({_MINI_WHY}); the offset alone +0.8 on diffuse_shadow; the light-view "
            "group: see shadow_resolution",
        ),
        "mlp_lr_init": Departure(
            "the networks get 20× fewer Adam steps than in a 60K run",
            f"measured with shadow_depth_offset, above ({_MINI_WHY}); " + _RATES,
        ),
        "mlp_lr_final": Departure(
            "the network rate × 5, as mlp_lr_init", "measured with mlp_lr_init"
        ),
        "mlp_lr_decay_from": Departure(
            "the decay ends within the 3000 steps (40K-60K at the 60K reference)",
            "measured with mlp_lr_init",
        ),
        "mlp_lr_max_steps": Departure(
            "the decay ends within the 3000 steps", "measured with mlp_lr_init"
        ),
        "asg_lr_max_steps": Departure(
            "the decay ends within the 3000 steps (the authors': 2000-4500 of 3000, "
            "1.6e-3 at the end)",
            "measured with num_asg; without it the lobe group gives +2.14 dB, within seed noise "
            "of +2.39",
        ),
    },
}

# The paper's grids switch terms off and reorder the phases on purpose (docs/ssdgs.md: measured on
# mini, 3 seeds).
_GRID = "docs/ssdgs.md, 'The composition ablation on mini' and 'The schedule ablation on mini'"
for _letter in "ABCDEF":
    DEPARTURES[f"ablation-{_letter}"] = {
        term: Departure(f"the paper's composition ablation {_letter} (Table 2)", _GRID)
        for term in ("use_shadow", "use_sss", "use_specular")
    }
for _letter in "HJK":
    DEPARTURES[f"schedule-{_letter}"] = {
        "schedule": Departure(f"the paper's schedule ablation {_letter}", _GRID)
    }

UNSWITCHABLE = (
    Unswitchable(
        "initial rotations",
        "scene/gaussian_model.py:257 (identity)",
        "random: identity rotations of isotropic Gaussians give every one the same normal",
    ),
    Unswitchable(
        "training views' refinement offsets",
        "scene/cameras.py:35-36 (one parameter per camera)",
        "one tensor per kind: Adam's momentum moves a view's offset a few steps after its last "
        "gradient",
    ),
    Unswitchable(
        "SSS network outputs",
        "scene/scatter_mlp.py:43-49 (r, σ_s', σ_a)",
        "(σ_s, σ_a, r) in the same ranges, another order of the last layer's rows",
    ),
)

AUTHORS = AuthorsConfig(
    repository="irisfreesiri/SSD-GS",
    commit="26e42517e2c56cb2b943a18116560f292a06cd2c",
    values=VALUES,
    suite_fields=SUITE_FIELDS,
    departures=DEPARTURES,
    unswitchable=UNSWITCHABLE,
)
