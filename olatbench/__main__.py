"""``python -m olatbench``: the same as the ``olatbench`` command."""

from olatbench.cli import main

main(prog_name="olatbench")
