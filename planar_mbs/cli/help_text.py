"""How `mbs --help` shows options and how usage errors read.

typer names each option's value by its Python type (``<bool>`` for a flag, ``<list[str]>``,
``{model}``); `ReadableCommand` and `ReadableGroup` give each a name in words instead (``TIME``,
``NAME=VALUE``, ``MODEL``), nothing for a flag, and the choices of an option that has a few
(``rk4|dopri5|dop853``).  `use_one_error_style` makes click's usage errors (``--per-rev 0``, an
unknown option) read like every other error of the project: ``OPTION: error: ...`` and a hint,
not a box.
"""
from __future__ import annotations

import typer.core
from typer import rich_utils

from planar_mbs import catalog

from .common import console

# an option's value in words, by option name (first) or by the value's type
_BY_NAME = {
    "--set": "NAME=VALUE", "--param": "NAME=V1,V2,...", "--t-end": "TIME", "--output-step": "TIME", "--step": "TIME",
    "--from": "TIME", "--to": "TIME", "--period": "TIME", "--angle": "ANGLE", "--keep": "SIGNALS",
    "--against": "SIGNAL", "--poincare": "X:Y", "--orbit": "JOINT", "--clock": "BODY", "--scheduler": "ADDRESS",
    "--integrator": "|".join(catalog.names(catalog.INTEGRATORS)), "--rerun-signals": "envelope|full",
    "--signals": "envelope|full", "--format": "png|svg|pdf", "--rerun": "FILE.rrd",
}
_BY_TYPE = {"int": "N", "float": "NUMBER", "str": "TEXT", "Path": "PATH"}


def _name_value(param) -> None:
    """Set the metavar typer shows for `param`, unless one was given."""
    if param.metavar is not None:
        return
    if param.param_type_name == "argument":  # MODEL, [SIGNALS]... (typer: {model} and <path>)
        name = param.name.rstrip("_").upper()
        param.metavar = name
        usage = (name if param.required else f"[{name}]") + ("..." if param.nargs != 1 else "")
        param._usage_display_name = lambda: usage
        param.display_type_rich = lambda ctx: None
        return
    if getattr(param, "is_flag", False) or getattr(param, "is_bool_flag", False):
        param.metavar = ""
        return
    long = next((o for o in param.opts if o.startswith("--")), "")
    if long in _BY_NAME:
        param.metavar = _BY_NAME[long]
        return
    annotation = getattr(getattr(param, "type_descriptor", None), "annotation", None)
    name = getattr(annotation, "__name__", "")
    if name == "list":
        inner = typer.core.get_args(annotation) if hasattr(typer.core, "get_args") else ()
        name = getattr(inner[0], "__name__", "") if inner else ""
    param.metavar = _BY_TYPE.get(name, "VALUE")


def reflow(text: str | None) -> str | None:
    """A docstring's paragraphs each on one line, for typer's rich help, which keeps a docstring's line
    breaks and wraps again at the terminal's width, leaving ragged half-lines.  A paragraph with an
    indented line (an example) is kept as written."""
    if not text:
        return text
    paragraphs = []
    for para in text.split("\n\n"):
        lines = para.split("\n")
        paragraphs.append(para if any(line.startswith("  ") for line in lines) else
                          " ".join(line.strip() for line in lines))
    return "\n\n".join(paragraphs)


class ReadableCommand(typer.core.TyperCommand):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.help = reflow(self.help)

    def get_params(self, ctx):
        params = super().get_params(ctx)
        for p in params:
            _name_value(p)
        return params


class TwoWordCommand(ReadableCommand):
    """A command typed as two words (``mbs sweep replay``, routed to the hidden ``sweep-replay``):
    its usage line and its errors name it as typed."""

    def make_context(self, info_name, args, parent=None, **extra):
        return super().make_context((info_name or self.name).replace("-", " ", 1), args, parent=parent, **extra)


class ReadableGroup(typer.core.TyperGroup):
    def get_params(self, ctx):
        params = super().get_params(ctx)
        for p in params:
            _name_value(p)
        return params


def _project_error(exc) -> None:
    """click's usage error as ``WHERE: error: MESSAGE`` and ``hint: ...`` on stderr (cli.common's style)."""
    if type(exc).__name__ == "NoArgsIsHelpError":  # the help is already printed
        return
    ctx = getattr(exc, "ctx", None)
    param = getattr(exc, "param", None)
    where = ctx.command_path if ctx is not None else "mbs"
    if param is not None:
        opts = [o for o in getattr(param, "opts", []) if o.startswith("--")] or list(getattr(param, "opts", []))
        where = opts[0] if param.param_type_name == "option" and opts else (param.metavar or str(param.name).upper())
    message = getattr(exc, "message", None) or exc.format_message()
    message = message[0].lower() + message[1:] if message[:1].isupper() and message[1:2].islower() else message
    hint = f"`{ctx.command_path if ctx is not None else 'mbs'} --help` shows the usage"
    console(stderr=True).print(f"{where}: error: {message.rstrip('.')}\nhint: {hint}", markup=False, soft_wrap=True)


def use_one_error_style() -> None:
    """typer prints click's usage errors through `rich_utils.rich_format_error`: ours instead."""
    rich_utils.rich_format_error = _project_error
