"""``python -m olatbench.cli``: the same as the ``olatbench`` command."""

from olatbench.cli import main

main()
