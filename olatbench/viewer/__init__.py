"""``olatbench view``: an interactive relighting viewer for trained models
(optional extra ``olatbench[viewer]``).

Layers inside the package, bottom up: `geometry` (numpy: browser camera and light sliders ↔
olatbench records), `scheduler` (stdlib: one render in flight, stale requests dropped, progressive
resolution, refinement passes), `environment` (the environment-map mode's settings and menu),
`model` (a restored job: renders for display, ground truth and PSNR of dataset frames, progressive
relights under a map), `jobs` (which job folders to serve), `server` (the viser application,
imported only when a server starts). The viewer renders through `olatbench.bench.restore` (and
`olatbench.bench.relight` under a map) and imports no method.
"""
