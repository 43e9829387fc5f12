"""The leading `--flag VALUE` options of the drive scripts: `parse(args, defaults, doc)` takes
them off `args` (a list, changed in place) for the names in `defaults` (flag name without the
dashes -> default value, whose type the value is read as) and returns them as a dict; an unknown
flag or a missing or unreadable value exits with the message and `doc`."""
import sys


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
