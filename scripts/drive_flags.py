"""The leading `--flag VALUE` options of the drive scripts: `parse(args, defaults, doc)` takes
them off `args` (a list, changed in place) for the names in `defaults` (flag name without the
dashes -> default value, whose type the value is read as) and returns them as a dict; an unknown
flag or a missing or unreadable value exits with the message and `doc`."""
import os, sys


def parse(args, defaults, doc):
    values = dict(defaults)
    while args and args[0].startswith("--"):
        flag = args.pop(0)
        name = flag[2:]
        if name not in values:
            sys.exit(f"unknown option {flag}\n{doc}")
        try:
            values[name] = type(defaults[name])(args.pop(0))
        except (IndexError, ValueError):
            sys.exit(f"{flag} needs a value\n{doc}")
    return values


def eval_saved_options(args, doc):
    """`--starts N` (100; at least 5, the evaluation's own 5 among them) and `--bin PATH`
    (the repository's release build of drive_eval_saved) off `args`; exits with `doc` when no
    run folder is left."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    flags = parse(args, {"starts": 100,
                         "bin": os.path.join(root, "target/release/examples/drive_eval_saved")},
                  doc)
    if not args:
        sys.exit(doc)
    if flags["starts"] < 5:
        sys.exit("--starts must be at least 5 (the first 5 are the evaluation's)")
    return flags["starts"], flags["bin"]
