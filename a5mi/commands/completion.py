"""``a5mi completion bash|zsh``: a shell completion script for ``a5`` and ``a5mi``, generated from the flag tables.

Install with ``eval "$(a5mi completion bash)"`` (bash, or zsh through ``bashcompinit``), e.g. in ``~/.bashrc``.
Sub-commands, flags (every spelling) and file names complete; a flag that takes values completes file names.
"""

from __future__ import annotations

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Positional, choice
from a5mi.platform.errors import ExitStatus

_TEMPLATE = """\
# a5mi {version}: bash completion for a5 and a5mi (eval "$(a5mi completion bash)")
_a5mi_flags() {{
    case "$1" in
{cases}
    esac
}}
_a5mi_complete() {{
    local cur="${{COMP_WORDS[COMP_CWORD]}}" cmd sub
    cmd="$(basename -- "${{COMP_WORDS[0]}}")"
    if [[ "$cmd" == a5mi ]]; then
        if [[ $COMP_CWORD -eq 1 ]]; then
            COMPREPLY=($(compgen -W "{subcommands} --version -h --help" -- "$cur")); return
        fi
        sub="${{COMP_WORDS[1]}}"
    else
        sub=a5
    fi
    if [[ "$cur" == -* ]]; then
        COMPREPLY=($(compgen -W "$(_a5mi_flags "$sub")" -- "$cur"))
    else
        COMPREPLY=($(compgen -f -- "$cur"))
    fi
}}
complete -o filenames -F _a5mi_complete a5 a5mi
"""


def bash_script() -> str:
    """The bash completion script for every command of :data:`a5mi.cli.SUBCOMMANDS` and ``a5``."""
    from a5mi import __version__
    from a5mi.cli import SUBCOMMANDS, command
    from a5mi.commands.render import A5

    commands = {"a5": A5, **{name: command(name) for name in SUBCOMMANDS}}
    cases = []
    for name, cmd in commands.items():
        spellings = [n for f in cmd.all_flags for n in f.names
                     if cmd.grammar == "gnu" or not n.startswith("--") or n in ("--debug", "--help", "--version")]
        cases.append(f"        {name}) echo \"{' '.join(spellings)}\" ;;")
    return _TEMPLATE.format(version=__version__, cases="\n".join(cases), subcommands=" ".join(SUBCOMMANDS))


def run_completion(args: Args, console: Console) -> int:
    script = bash_script()
    if args.shell == "zsh":
        script = "autoload -U +X bashcompinit && bashcompinit\n" + script
    console.result(script.rstrip("\n"))
    return ExitStatus.OK


def _check_shell(args: Args) -> None:
    choice(("bash", "zsh"))("SHELL", [args.shell])


COMPLETION = Command("completion", 'Print a shell completion script for a5 and a5mi (eval "$(a5mi completion bash)").',
                     (), run_completion, (Positional("shell", "SHELL", "bash or zsh"),), check=_check_shell,
                     exit_ok="the script printed")
