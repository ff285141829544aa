"""The command line shared by the scripts in tools/: an argparse parser
described by the script's own docstring, and path arguments that refuse
what looks like an option (so `script.py --help` prints help instead of
writing a file named `--help`, and `script.py -o.glb` is an error)."""
import argparse


def parser(doc):
    """A parser whose description is the script's docstring, kept as written."""
    return argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def path(value):
    """An argparse type for a file or folder path that does not start with '-'."""
    if value.startswith("-"):
        raise argparse.ArgumentTypeError(
            f"{value!r} looks like an option, not a path (write ./{value} for a file of that name)"
        )
    return value
