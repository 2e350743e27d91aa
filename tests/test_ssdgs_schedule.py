"""SSD-GS schedules, config scaling and preset composition (no rendering)."""

from __future__ import annotations

import pytest

from olatbench.methods.ssdgs.config import SSDGSConfig
from olatbench.methods.ssdgs.presets import PRESETS
from olatbench.methods.ssdgs.schedule import SCHEDULES, get_schedule
from olatbench.methods.ssdgs.spec import SPEC


def test_schedule_i_matches_the_paper() -> None:
    s = SCHEDULES["I"]
    assert [s.is_enabled("shadow", i) for i in (4_999, 5_000)] == [False, True]
    assert [s.is_enabled("sss", i) for i in (8_999, 9_000)] == [False, True]
    assert [s.is_enabled("specular", i) for i in (15_999, 16_000)] == [False, True]
    assert [s.is_frozen("shadow_mlp", i) for i in (8_999, 9_000, 15_999, 16_000)] == [
        False,
        True,
        True,
        False,
    ]
    assert [s.is_frozen("sss_mlp", i) for i in (12_999, 13_000, 19_999, 20_000)] == [
        False,
        True,
        True,
        False,
    ]
    assert [s.is_frozen("asg_lobes", i) for i in (15_999, 16_000, 21_999, 22_000)] == [
        False,
        True,
        True,
        False,
    ]
    assert (s.refine_camera_from, s.refine_light_from) == (5_000, 16_000)


def test_schedules_h_j_k() -> None:
    h, j, k = SCHEDULES["H"], SCHEDULES["J"], SCHEDULES["K"]
    assert all(h.is_enabled(t, 0) for t in ("shadow", "sss", "specular")) and not h.frozen
    assert j.enable["specular"] < j.enable["sss"]
    assert set(k.enable.values()) == {5_000} and not k.frozen


def test_schedule_scaling_with_the_run_length() -> None:
    half = get_schedule("I", 100_000, 50_000)
    assert half.enable == {"shadow": 2_500, "sss": 4_500, "specular": 8_000}
    assert half.frozen["asg_lobes"] == ((8_000, 11_000),)
    assert "shadow on" in "\n".join(half.timeline())
    # The 60K SSS-GS runs use the same absolute thresholds (the official script); mini compresses
    # them.
    assert SPEC.resolve_config("sssgs").resolved_schedule().enable["specular"] == 16_000
    mini = SPEC.resolve_config("mini").resolved_schedule()
    assert mini.enable == {"shadow": 250, "sss": 450, "specular": 800}


def test_presets_compose_left_to_right() -> None:
    cfg = SPEC.resolve_config("mini+ablation-C+schedule-K")
    assert cfg.iterations == 3_000 and cfg.schedule == "K"
    assert (cfg.use_specular, cfg.use_sss, cfg.use_shadow) == (True, True, False)
    assert SPEC.resolve_config("nrhints").refine_camera
    assert not SPEC.resolve_config("sssgs-no-opt").refine_light
    assert SPEC.resolve_config("gs3").background == (1.0, 1.0, 1.0)
    assert SPEC.resolve_config("shadow-on-sss").shadow_on_sss
    for name in (
        "nrhints",
        "gs3",
        "sssgs",
        "sssgs-no-opt",
        "mini",
        *(f"ablation-{c}" for c in "ABCDEF"),
        *(f"schedule-{c}" for c in "HIJK"),
        "shadow-on-sss",
    ):
        assert name in PRESETS
        SPEC.resolve_config(name)
    with pytest.raises(KeyError, match="known presets"):
        SPEC.resolve_config("mini+ablation-Z")


def test_config_rejects_unknown_choices() -> None:
    with pytest.raises(ValueError, match="dipole_virtual_factor"):
        SSDGSConfig(dipole_virtual_factor="both")
    with pytest.raises(ValueError, match="schedule"):
        SSDGSConfig(schedule="Q")
    assert SSDGSConfig(iterations=3_000, reference_iterations=60_000).steps(20_000) == 1_000
