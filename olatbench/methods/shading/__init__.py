"""Shading blocks shared by the relightable Gaussian methods (SSD-GS and GS³); no method package
owns them.

`terms` (closed-form per-Gaussian terms: shading frames, Lambert cosine, Schlick Fresnel,
inverse-square irradiance), `asg` (the anisotropic-spherical-Gaussian specular mixture),
`shadow_mlp` (the network refining the light-view visibility), `encoding` (positional and frequency
encodings) and `mlp` (the plain MLP body).
"""
