"""``python -m app.bench NAME [args]`` — dispatch to ``app.bench.NAME.main(args)``."""

from __future__ import annotations

import importlib
import sys

BENCHES = ("perception", "triangulation", "radar")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] not in BENCHES:
        print(f"usage: python -m app.bench {{{','.join(BENCHES)}}} [--json] [options]", file=sys.stderr)
        return 2
    module = importlib.import_module(f"app.bench.{args[0]}")
    return int(module.main(args[1:]))


if __name__ == "__main__":
    sys.exit(main())
