"""How much each shading term of a trained SSD-GS model contributes, and where Θ_SSS's dipole sits.

    python examples/component_shares.py runs/mini/ssdgs/default/translucent/seed0 [more job folders]

For each finished SSD-GS job folder: the job's test views are rendered with every component
(`SSDGS.render`), and over the foreground pixels (rendered rgb sum > 0.02, linear) of all of them it
prints

* ``diffuse`` / ``specular`` / ``sss``: the term's radiance summed over those pixels, as a fraction
  of the rendered rgb's (diffuse and specular are unshadowed, so their shares exceed 1 where S
  darkens them);
* ``S``: the mean shadow factor over those pixels;
* the 10 / 50 / 90 % quantiles over Gaussians × test views of Θ_SSS's dipole parameters σ_s, σ_a
  (1/scene unit), r (scene units) and of the profile f_sss, each Gaussian seen with that view's ωo,
  ωi and normal. The parameters are sigmoids rescaled into fixed ranges (σ in [0.05, 2.05], r in
  [0.1, 3.1]), so a quantile at a range's end means the network has saturated there (no gradient
  flows back through it).

Uses the public restore API (`olatbench.bench.restore.restore`), so it doubles as an example of
inspecting a trained model from another script. CPU is fine: a mini job takes seconds.
"""

from __future__ import annotations

import sys

import numpy as np
import torch

from olatbench.bench.restore import restore
from olatbench.bench.views import view_camera
from olatbench.datasets import load_scene
from olatbench.methods.shading.terms import safe_normalize
from olatbench.methods.ssdgs.sss import dipole_profile
from olatbench.methods.training import camera_centre

QUANTILES = (0.1, 0.5, 0.9)
FOREGROUND = 0.02  # a pixel is foreground when its rendered rgb sums above this (linear)


@torch.no_grad()
def dipole_parameters(method, camera, light) -> dict[str, torch.Tensor]:
    """Θ_SSS's (σ_s, σ_a, r) and f_sss (each (N,)) for every Gaussian seen from ``camera`` lit by
    ``light``."""
    model, shader = method.model, method.shader
    positions, attributes = model.means, model.attributes
    w2c = torch.as_tensor(camera.w2c(), dtype=positions.dtype)
    wo = safe_normalize(camera_centre(w2c)[None, :] - positions)
    wi = safe_normalize(torch.as_tensor(light.position, dtype=positions.dtype)[None, :] - positions)
    normals = shader.frames(attributes, model.quats, model.scales, wo)[:, :, 2]
    net = shader.sss_net
    sigma_s, sigma_a, r = net.parameters_from_input(
        net.encode(positions, wo, wi, normals, attributes["material"])
    )
    # what net(...) returns, unrecomputed
    f_sss = dipole_profile(r, sigma_s, sigma_a, net.eta, net.virtual_factor)
    return {"sigma_s": sigma_s[:, 0], "sigma_a": sigma_a[:, 0], "r": r[:, 0], "f_sss": f_sss[:, 0]}


def main(folders: list[str]) -> None:
    for folder in folders:
        method, job = restore(folder)
        if job.method != "ssdgs":
            sys.exit(f"{folder}: a '{job.method}' job; this script reads SSD-GS models only")
        frames = load_scene(job.scene_path, format=job.scene_format).split("test")
        sums = dict.fromkeys(("rgb", "diffuse", "specular", "sss"), 0.0)
        shadow, parameters = 0.0, {}
        for frame in frames:
            camera = view_camera(frame, job)
            out = method.render(camera, frame.light)
            mask = out["rgb"].sum(-1) > FOREGROUND
            for name in sums:
                sums[name] += float(out[name][mask].sum())
            shadow += float(out["shadow"][mask].mean()) / len(frames)
            for name, value in dipole_parameters(method, camera, frame.light).items():
                parameters.setdefault(name, []).append(value)
        shares = " ".join(
            f"{name}={sums[name] / sums['rgb']:.4f}" for name in ("diffuse", "specular", "sss")
        )
        print(f"{folder}: {shares} S={shadow:.3f}")
        for name, values in parameters.items():
            quantiles = np.quantile(torch.cat(values).numpy(), QUANTILES)
            print(f"  {name:8s} " + " ".join(f"{x:.5g}" for x in quantiles))


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) > 1 else 2)
    main(sys.argv[1:])
