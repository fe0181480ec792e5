"""``python -m seqdesign.cli``: the command line, as the ``seqdesign`` script runs it."""

from seqdesign.cli import main

main()
