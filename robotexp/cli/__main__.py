"""`python -m robotexp.cli ARGS`: the `robotexp` command."""

from robotexp.cli.main import main

main()
