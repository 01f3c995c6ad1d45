# SPDX-License-Identifier: Apache-2.0
"""Command line: ``h4pin table2`` (the paper's Table II), ``h4pin view`` (meshcat viewer),
``h4pin export --out PATH`` (MuJoCo model), the studies; one module per command, what they share
in :mod:`h4pin.cli.common`; ``docs/cli.md`` lists every command and option (:func:`reference`
writes it).

One convention: ``--model`` is ``paper`` unless told (as :func:`h4pin.compliance`; ``cycle``:
:data:`~h4pin.cli.common.CYCLE_MODEL`); enumerations (``--model``, ``--variant``) are choices;
``--out PATH`` is a command's main output (a file, or a store for a sweep), ``--figure PATH`` its
picture (PNG) and ``--figures DIR`` a folder of them; ``--quiet`` hides progress bars;
``--payload KG`` is a point mass at D in kg (>= 0).

Outputs: an existing file is replaced only if h4pin wrote it (:func:`h4pin.files.written_by_h4pin`)
or with ``--overwrite``; otherwise the command exits 2 before any work and the file is untouched.

Errors a user can act on (unreachable or singular pose, bad parameter, malformed URDF, bad
arguments) print one line on stderr and exit with status 2; nothing is half-written. ``h4pin``
alone prints the help (exit 0), ``h4pin --version`` the version.

``h4pin view`` without ``--out`` serves the scene until it is stopped. Whatever stops it, its
meshcat server stops too, and the exit status says why, as shells do for a signal (128 + its
number): Ctrl-C (SIGINT) exits 130, SIGTERM 143, SIGHUP (terminal closed) 129. A signal the
command was started with ignored (``nohup``, a shell's background job) stays ignored.
"""

from __future__ import annotations

import inspect
import signal
import sys

import typer
import typer.main

from h4pin.cli import atlas, calibrate, cycle, export, modes, sweep, table2, tolerance, view, warmup
from h4pin.cli.common import Stopped, app, check_arity
from h4pin.errors import H4Error

#: The commands, in the order docs/cli.md lists them: one module each.
COMMANDS = (table2.table2, view.view, tolerance.tolerance, export.export, atlas.atlas, sweep.sweep, cycle.cycle,
            modes.modes, calibrate.calibrate, warmup.warmup)
for _command in COMMANDS:  # --help lists each command with its whole first paragraph, not cut
    app.command(short_help=" ".join(inspect.cleandoc(_command.__doc__ or "").split("\n\n")[0].split()))(_command)
#: How docs/cli.md is made (its first line says so).
REGENERATE = ".venv/bin/python -c 'from h4pin.cli import reference; print(reference(), end=\"\")' > docs/cli.md"


def reference() -> str:
    """``docs/cli.md``: every command and option of ``h4pin``, in Markdown, from the click command
    tree of the CLI itself (what ``--help`` prints: the same names, values and defaults)."""
    group = typer.main.get_command(app)
    root = group.context_class(group, info_name="h4pin")
    out = [f"<!-- Generated from the CLI by h4pin.cli.reference(); do not edit. Regenerate: {REGENERATE} -->",
           "", "# Command line reference", "",
           f"`h4pin COMMAND [OPTIONS]`: {inspect.cleandoc(group.help or '')} Every command also takes `--help`. "
           "An error prints one line (`error: ...`) and exits with status 2.", "",
           "Conventions: `--out PATH` is a command's main output, `--figure PATH` its picture (PNG), "
           "`--figures DIR` a folder of pictures; an existing file is replaced only if h4pin wrote it, or with "
           "`--overwrite`. `--model` is `paper` unless told (as `h4pin.compliance`; `cycle` aside), `--quiet` hides "
           "progress bars, "
           "`--payload KG` is a point mass at D in kg.", ""]
    for name, command in group.commands.items():
        ctx = command.context_class(command, info_name=name, parent=root)
        out += [f"## h4pin {name}", "", inspect.cleandoc(command.help or ""), ""]
        for param in command.get_params(ctx):
            if param.name == "help":
                continue
            if getattr(param, "hidden", False):
                continue
            record = param.get_help_record(ctx)
            if record is not None:
                decl, text = record
                out.append(f"- `{decl}`: {text}" if text else f"- `{decl}`")
        out.append("")
    return "\n".join(out) + "\n"


#: Commands that call the compiled kernel directly (the others start on the numpy path while it
#: compiles in the background: h4pin._jit).
COMPILING = ("tolerance", "atlas", "sweep")


def note_first_compile(argv: list[str]) -> None:
    """Say so on stderr before a command whose first run compiles the kernels."""
    if argv and argv[0] in COMPILING and "--help" not in argv and "--robot" not in argv:
        from h4pin.stiffness import kernel

        if not kernel.cached():
            typer.echo("h4pin: first run: compiling the compliance kernels (1-3 min, once; cached afterwards; "
                       "`h4pin warmup` does it ahead)", err=True)


def main() -> None:
    """Entry point of the ``h4pin`` console script: errors are one line and exit status 2."""
    try:
        check_arity(sys.argv[1:])
        note_first_compile(sys.argv[1:])
        code = app(standalone_mode=False)
    except (H4Error, ValueError, FileNotFoundError) as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except MemoryError:  # the estimates switched off (H4PIN_MEMORY_LIMIT=0), or wrong: still one line
        typer.echo("error: out of memory: the job does not fit in this machine's memory; make it smaller "
                   "(fewer poses, samples or designs), or set H4PIN_MEMORY_LIMIT to have it refused up front", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        sys.exit(128 + signal.SIGINT)
    except Stopped as stop:
        sys.exit(128 + stop.signum)
    except Exception as exc:
        if isinstance(exc.__cause__ or exc.__context__, KeyboardInterrupt):  # click's Abort after Ctrl-C
            sys.exit(128 + signal.SIGINT)
        # Usage errors of typer's click (vendored or not): one line instead of a usage box.
        if hasattr(exc, "format_message"):
            if exc.format_message():  # empty after the help printed for a bare `h4pin`
                message = exc.format_message().replace(": Value error, ", ": ")  # typer's coercion says so
                typer.echo(f"error: {message}", err=True)
            sys.exit(2)
        if hasattr(exc, "exit_code"):
            sys.exit(exc.exit_code)
        raise
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
