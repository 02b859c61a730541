"""``python -m tests.conformance --regenerate [--only FAMILY ...]``."""

import argparse
import sys

from tests.conformance import families, regenerate


def main() -> int:
    """Regenerate conformance vectors; refuses to run without the explicit flag."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--regenerate", action="store_true",
                        help="rewrite the vectors (never done by the test suite)")
    parser.add_argument("--only", nargs="*", choices=families(), help="families to rewrite")
    args = parser.parse_args()
    if not args.regenerate:
        parser.error("nothing to do: pass --regenerate to rewrite spec/vectors/")
    for name in regenerate(args.only):
        print(f"regenerated spec/vectors/{name}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
