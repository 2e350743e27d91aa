"""Names that tie a run to a row of the SSD-GS paper's tables, shared by the method specs (which define the runs)
and the reports (which pick the row), so that neither layer imports the other."""

from __future__ import annotations

SSDGS_REFINED_VARIANT = "opt"
"""ssdgs-official's preset that refines cameras and lights (``--cam_opt --pl_opt``): the paper's "Ours (w/ Opt)"."""
