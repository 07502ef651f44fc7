"""``python -m app.bench NAME [args]`` — dispatch to ``app.bench.NAME.main(args)``."""

from __future__ import annotations

import importlib
import sys

from app.cli import run_cli

BENCHES = ("perception", "triangulation", "radar")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args[:1] in (["-h"], ["--help"]):
        print(f"{__doc__}\nBenches: {', '.join(BENCHES)}; python -m app.bench NAME --help lists a bench's options.")
        return 0
    if not args or args[0] not in BENCHES:
        name = repr(args[0]) if args else "none"
        print(f"python -m app.bench: error: unknown bench {name}; one of {', '.join(BENCHES)}", file=sys.stderr)
        return 2
    module = importlib.import_module(f"app.bench.{args[0]}")
    return int(module.main(args[1:]))


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m app.bench"))
