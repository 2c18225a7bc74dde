"""``dsage-ray checkpoint convert``: rewrite checkpoints of dsage_ray before format 3 once, for a trusted owner.

Checkpoints and pretrained surrogates of earlier versions were plain pickles, which run code when opened, so this
version refuses them (:mod:`dsage_ray.core.checkpoint`). Converting reads such a file the old way, which runs
whatever code it holds, so the command asks for ``--trust``; the converted file opens without running code.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from dsage_ray.errors import InputError

EXAMPLES = """\
examples:
  dsage-ray checkpoint convert tb_logs/audit-dcd_accel-20261120-0900 --trust   # every checkpoint in the folder
  dsage-ray checkpoint convert tb_logs/accel.surrogate --trust                  # a pretrained surrogate
"""


def add_subparser(subparsers) -> None:
    parser = subparsers.add_parser(
        "checkpoint", help="convert checkpoints of earlier dsage_ray versions (runs their code: trusted files only)",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES,
        description="Checkpoints (checkpoint.dsage) and pretrained surrogates written before format 3 were plain "
                    "pickles: opening one runs any code it holds, so this version refuses them. `convert` rewrites "
                    "them in the current format, which opens without running code. Converting reads the old file, "
                    "so only convert files you made or whose sender you trust.")
    commands = parser.add_subparsers(dest="checkpoint_command", required=True)
    convert = commands.add_parser("convert", help="rewrite format-2 checkpoints in place (runs their code)",
                                  formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES)
    convert.add_argument("paths", nargs="+", metavar="PATH",
                         help="a checkpoint file, a pretrained surrogate, or a folder (every checkpoint.dsage in it)")
    convert.add_argument("--trust", action="store_true",
                         help="required: you trust these files (reading the old format runs the code they hold)")
    convert.set_defaults(handler=convert_command)


def convert_command(args: argparse.Namespace) -> int:
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, convert_trusted_checkpoint

    if not args.trust:
        raise InputError("converting reads the old format, which runs any code the file holds; if you made these "
                         "files or trust their sender, add --trust")
    files: list[Path] = []
    for path in map(Path, args.paths):
        found = sorted(path.rglob(CHECKPOINT_NAME)) if path.is_dir() else [path]
        if not found:
            raise InputError(f"{path}: a folder without a {CHECKPOINT_NAME}")
        files += found
    for file in files:
        convert_trusted_checkpoint(file)
        print(f"converted: {file}")
    return 0
