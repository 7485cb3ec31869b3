"""Typed command lines from the config dataclasses (tyro), shared by every command of the project.

A command is a frozen dataclass ``Args`` whose fields are its options: the type is the option's
type, the default the option's default, the docstring under the field its ``--help`` text, and
``__post_init__`` rejects bad values (tyro prints the message and exits with status 2). Then::

    def main(argv: list[str] | None = None) -> int:
        args = parse(Args, argv, __doc__)
        ...

``field_name`` becomes ``--field-name``; a ``bool`` becomes ``--flag`` / ``--no-flag``; a
``tuple[int, ...]`` takes several values (``--particles 50 100``). A ``runner: Runner = RunnerConfig()``
field adds the experiment runner's options (``--executor``, ``--workers``, ``--address``,
``--progress``) without a prefix.

Every command is a console entry point (``[project.scripts]`` in pyproject.toml) and a file in
``scripts/`` that calls the same ``main``.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import shlex
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Annotated, Any, TypeVar

import tyro

from filters.experiments.runner import RunnerConfig

__all__ = ["JsonDict", "Runner", "parse", "command", "command_line", "usage_error"]

T = TypeVar("T")

Runner = tyro.conf.OmitArgPrefixes[RunnerConfig]
"""Annotation of an ``Args`` field holding the runner's options, flags without a ``runner.`` prefix."""


def _json_object(args: list[str]) -> dict[str, Any]:
    try:
        value = json.loads(args[0])
    except json.JSONDecodeError as e:
        raise ValueError(f"not JSON: {e}") from None
    if not isinstance(value, dict):
        raise ValueError(f'expected a JSON object ({{"key": value, ...}}), got {args[0]!r}')
    return value


JsonDict = Annotated[
    dict[str, Any],
    tyro.constructors.PrimitiveConstructorSpec(
        nargs=1,
        metavar="JSON",
        instance_from_str=_json_object,
        is_instance=lambda x: isinstance(x, dict),
        str_from_instance=lambda x: [json.dumps(x)],
    ),
]
"""Annotation of an ``Args`` field holding keyword arguments of free form (a dict), given on the command
line as one JSON object: ``--config.planner '{"replan_every": 5}'``."""


OUTPUT_FIELDS = ("out", "doc", "figure", "fig_dir", "figures", "log_dir")
"""Option names that hold a path a command writes: checked before any work (`check_common_options`)."""

FOLDER_FIELDS = ("out", "fig_dir", "figures", "log_dir")
"""Those of `OUTPUT_FIELDS` that name a folder, unless the command's ``Args`` lists the field in its class attribute
``file_outputs`` (paper 000's ``out`` is its report's file); the others name a file."""


def parse(cls: type[T], argv: Sequence[str] | None = None, description: str | None = None) -> T:
    """``cls`` filled from ``argv`` (default: ``sys.argv[1:]``); ``--help`` prints every option. Seeds and
    output paths are checked as well (`check_common_options`): a bad one exits with status 2, before any work."""
    args = tyro.cli(cls, args=None if argv is None else list(argv), description=description)
    try:
        check_common_options(args)
    except (ValueError, OSError) as e:  # OSError: a folder on the way that cannot be read
        raise SystemExit(usage_error(_prog(), e)) from None
    return args


def _prog() -> str:
    return Path(sys.argv[0]).stem if sys.argv and sys.argv[0] else "command"


def check_common_options(args: Any, prefix: str = "") -> None:
    """ValueError for what every command's options share, in ``args`` and the dataclasses it holds: a seed
    (an int, or ints, in a field whose name holds ``seed``) below 0, which NumPy's generators refuse; an
    output path (`OUTPUT_FIELDS`) under an existing file, which no command could write; a folder's path that is a
    file, and a file's path that is a folder (`FOLDER_FIELDS`)."""
    if not dataclasses.is_dataclass(args):
        return
    for f in dataclasses.fields(args):
        v = getattr(args, f.name)
        name = f"--{prefix}{f.name.replace('_', '-')}"
        if dataclasses.is_dataclass(v):
            check_common_options(v, f"{prefix}{f.name.replace('_', '-')}.")
        elif "seed" in f.name:
            values = v if isinstance(v, (tuple, list)) else (v,)
            if any(isinstance(x, int) and not isinstance(x, bool) and x < 0 for x in values):
                raise ValueError(f"{name} must be an integer >= 0, got {v!r}")
        elif f.name in OUTPUT_FIELDS and isinstance(v, (str, Path)) and str(v):
            path = Path(v).expanduser().absolute()
            folder = f.name in FOLDER_FIELDS and f.name not in getattr(args, "file_outputs", ())
            if folder and path.exists() and not path.is_dir():
                raise ValueError(f"{name} {str(v)!r} is a file, not a folder")
            if not folder and path.is_dir():  # found out only when the report is written, after all the work
                raise ValueError(f"{name} {str(v)!r} is a folder: give the path of the file to write")
            for parent in path.parents:
                if parent.exists():
                    if not parent.is_dir():
                        raise ValueError(f"{name} {str(v)!r}: {str(parent)!r} is a file, not a folder")
                    break


def command(main: Callable[..., int]) -> Callable[..., int]:
    """Decorate a command's ``main(argv)``: Ctrl-C ends it with ``prog: interrupted`` instead of a traceback.
    From the command line (``argv`` None) the process then dies of SIGINT, as an uncaught Ctrl-C does, so a
    calling shell loop stops too (status 130 in the shell); called with ``argv``, ``main`` returns 130. What the
    command wrote by then is its own business: the project's commands write their results at the end."""

    @functools.wraps(main)
    def wrapped(argv: list[str] | None = None, *args, **kwargs) -> int:
        try:
            return main(argv, *args, **kwargs)
        except KeyboardInterrupt:
            print(f"{_prog()}: interrupted", file=sys.stderr)
            if argv is None:  # run from the command line: die of SIGINT, so that a calling shell loop stops too
                sys.stdout.flush()
                sys.stderr.flush()
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                os.kill(os.getpid(), signal.SIGINT)
            return 130

    return wrapped


def command_line(script: str, argv: Sequence[str]) -> str:
    """The shell command that reruns ``script`` (a path under ``scripts/``) with ``argv``, quoted."""
    return " ".join(["python", script, *(shlex.quote(a) for a in argv)])


def usage_error(prog: str, message: object) -> int:
    """Print ``prog: error: message`` to stderr as argparse does, and return its exit status, 2.

    For input a command can only judge after parsing (a file that cannot be read, a value beyond
    what the data holds): ``return usage_error("replay_log", e)`` instead of a traceback."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    return 2
