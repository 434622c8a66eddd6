"""``python -m fusion``: the ``fusion`` command."""

from __future__ import annotations

from fusion.cli import main

main()
