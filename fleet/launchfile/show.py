"""What `ros2 launch --show-args` and `ros2 launch --print` print, for a description."""

from __future__ import annotations

from fleet.launchfile import description as d
from fleet.launchfile.substitutions import Text, written


def _describe(text: Text) -> str:
    """A default value as launch describes it: `'text' + LaunchConfig('x')`."""
    tokens = []
    for part in text:
        if isinstance(part, str):
            tokens.append(f"'{part}'")
        elif part.kind == "var":
            tokens.append(f"LaunchConfig({' + '.join(_describe(arg) for arg in part.args)})")
        elif part.kind == "env":
            tokens.append(f"EnvVar({_describe(part.args[0])})")
        else:
            tokens.append(written((part,)))
    return " + ".join(tokens)


def _arguments(actions: list[d.Action], conditional: bool) -> list[tuple[d.DeclareArgument, bool]]:
    """Declared arguments as launch's get_launch_arguments finds them: also in groups, marked
    conditional under a condition or a timer; not those of included files."""
    found: list[tuple[d.DeclareArgument, bool]] = []
    for action in actions:
        under = conditional or action.condition is not None
        if isinstance(action, d.DeclareArgument):
            found.append((action, under))
        elif isinstance(action, d.Group):
            found += _arguments(action.actions, under)
        elif isinstance(action, d.Timer):
            found += _arguments(action.actions, True)
    return found


def _argument_description(argument: d.DeclareArgument) -> str:
    choices = None if argument.choices is None else list(argument.choices)
    if argument.description is None:
        return "no description given" if choices is None else f"One of: {choices}"
    text = argument.description
    if choices is not None:
        text = (text if text.endswith(".") else text + ".") + f" Valid choices are: {choices}"
    return text


def arguments_text(description: d.LaunchDescription) -> str:
    lines = ["Arguments (pass arguments as '<name>:=<value>'):"]
    found = _arguments(description.actions, False)
    seen: set[str] = set()
    for argument, conditional in found:
        if argument.name in seen:
            continue
        seen.add(argument.name)
        entry = f"\n    '{argument.name}':{'*' if conditional else ''}\n        {_argument_description(argument)}"
        if argument.default is not None:
            entry += f"\n        (default: {_describe(argument.default) if argument.default else repr('')})"
        lines.append(entry)
    if not found:
        lines.append("\n  No arguments.")
    elif any(conditional for _, conditional in found):
        lines.append("\n* argument(s) which are only used if specific conditions occur")
    return "\n".join(lines)


def description_text(description: d.LaunchDescription) -> str:
    """The description as a tree, in the shape `ros2 launch --print` prints (which names only
    the classes of launch's objects; here each action says what it does)."""
    lines = [f"<LaunchDescription {description.path}>"]
    _tree(description.actions, "", lines)
    return "\n".join(lines)


def _tree(actions: list[d.Action], indent: str, lines: list[str]) -> None:
    for index, action in enumerate(actions):
        last = index == len(actions) - 1
        lines.append(f"{indent}{'└── ' if last else '├── '}{_summary(action)}")
        children: list[d.Action] = []
        if isinstance(action, d.Group | d.Timer):
            children = action.actions
        _tree(children, indent + ("    " if last else "│   "), lines)


def _summary(action: d.Action) -> str:
    def w(text: Text | None) -> str:
        return "None" if text is None else repr(written(text))

    condition = "" if action.condition is None else f", {action.condition.keyword}={w(action.condition.text)}"
    if isinstance(action, d.DeclareArgument):
        fields = f"{action.name!r}, default={w(action.default)}"
        if action.choices is not None:
            fields += f", choices={list(action.choices)}"
        return f"DeclareLaunchArgument({fields}{condition})"
    if isinstance(action, d.SetConfiguration):
        return f"SetLaunchConfiguration({w(action.name)}, {w(action.value)}{condition})"
    if isinstance(action, d.SetEnv):
        return f"SetEnvironmentVariable({w(action.name)}, {w(action.value)}{condition})"
    if isinstance(action, d.UnsetEnv):
        return f"UnsetEnvironmentVariable({w(action.name)}{condition})"
    if isinstance(action, d.PushNamespace):
        return f"PushRosNamespace({w(action.namespace)}{condition})"
    if isinstance(action, d.Group):
        scoped = action.scoped if isinstance(action.scoped, bool) else w(action.scoped)
        return f"GroupAction(scoped={scoped}{condition})"
    if isinstance(action, d.Timer):
        period = action.period if isinstance(action.period, float) else w(action.period)
        return f"TimerAction(period={period}{condition})"
    if isinstance(action, d.Include):
        arguments = ", ".join(f"{written(name)}:={written(value)}" for name, value in action.arguments)
        return f"IncludeLaunchDescription({w(action.file)}, arguments=[{arguments}]{condition})"
    if isinstance(action, d.Log):
        return f"LogInfo({w(action.message)}{condition})"
    if isinstance(action, d.SetParameter):
        return f"SetParameter({w(action.name)}, {w(action.value)}{condition})"
    if isinstance(action, d.SetRemap):
        return f"SetRemap({w(action.source)} -> {w(action.target)}{condition})"
    if isinstance(action, d.Executable):
        return f"ExecuteProcess(cmd={w(action.cmd)}{condition})"
    assert isinstance(action, d.Node)
    fields = f"package={w(action.package)}, executable={w(action.executable)}"
    if action.name is not None:
        fields += f", name={w(action.name)}"
    if action.namespace is not None:
        fields += f", namespace={w(action.namespace)}"
    return f"Node({fields}{condition})"
