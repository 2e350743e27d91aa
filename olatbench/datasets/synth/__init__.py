"""Synthetic OLAT scenes rendered with Mitsuba 3 (optional extra ``olatbench[synth]``)."""
