"""Print pathpref's benchmark figures as JSON (the same as `pathpref bench --json`).

    python scripts/bench.py [--quick] [--maps simple office classroom]
"""

import sys

from pathpref.apps.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "--json", *sys.argv[1:]]))
