"""Write the evaluation suites (plate_env/data/suites/*.json) and print their content hashes to pin; ``--check``
compares the files with a rebuild instead. The builder is the package's (:mod:`plate_env.build.suites`); one suite:
``plate-env build suite NAME --out FILE``.

    python experiments/make_suites.py [--check]
"""

from __future__ import annotations

import argparse
import json
import sys

from plate_env.bench.suites import content_hash, suite_dir
from plate_env.build.suites import suite_names, suite_text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare with the files instead of writing them")
    args = ap.parse_args()
    bad = 0
    for name in suite_names():
        path, text = suite_dir() / f"{name}.json", suite_text(name)
        if args.check:
            same = path.is_file() and path.read_text() == text
            bad += not same
            print(f"{name}: {'same' if same else 'DIFFERS'}")
            continue
        path.write_text(text)
        print(f'    "{name}": "{content_hash(json.loads(text))}",')
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
