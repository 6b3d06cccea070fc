"""RL Zoo's hyper-parameter dialect, read without evaluating code.

The zoo writes some values as Python expressions in strings, e.g.
``policy_kwargs: "dict(net_arch=dict(pi=[64, 64], vf=[64, 64]), activation_fn=nn.Tanh)"``,
and ``rl_zoo3.train`` ``eval``-uates them. :func:`parse_expression` reads the same strings
from a restricted grammar instead, so a run config taken from elsewhere never runs code:
numbers, strings, ``True``/``False``/``None``, lists, tuples, ``{...}`` and ``dict(k=v, ...)``,
and the names of :data:`ALLOWED_NAMES` (torch activation modules and optimisers, as ``nn.X``,
``th.nn.X`` or ``torch.nn.X``). Anything else raises ``ValueError`` naming what was refused.

:func:`zoo_yaml_load` reads the zoo's ``config.yml`` / ``args.yml``, which it writes with
``yaml.dump`` of an ``OrderedDict`` (the ``!!python/object/apply:collections.OrderedDict``
tag): that tag becomes a plain dict, every other Python tag is refused (a safe loader).
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import yaml

#: Names a zoo expression may use -> (module, attribute). Resolved only when used.
ALLOWED_NAMES: dict[str, tuple[str, str]] = {
    **{f"nn.{n}": ("torch.nn", n) for n in (
        "Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "Mish",
        "SELU", "Identity")},
    **{f"optim.{n}": ("torch.optim", n) for n in ("Adam", "AdamW", "RMSprop", "SGD")},
}
#: Lower-case activation names of the project's earlier YAML (``activation_fn: tanh``).
ACTIVATION_ALIASES = {"tanh": "nn.Tanh", "relu": "nn.ReLU", "elu": "nn.ELU",
                      "leaky_relu": "nn.LeakyReLU"}


def _dotted(node: ast.AST) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return f"{_dotted(node.value)}.{node.attr}"
    raise ValueError(f"unsupported expression {ast.unparse(node)!r}")


def resolve_name(name: str) -> Any:
    """The object of an allowed dotted name (``nn.Tanh``, ``th.nn.Tanh``, ``torch.nn.Tanh``)."""
    import importlib

    short = name.removeprefix("torch.").removeprefix("th.")
    short = ACTIVATION_ALIASES.get(short, short)
    if short not in ALLOWED_NAMES:
        raise ValueError(f"name {name!r} is not allowed (allowed: {', '.join(ALLOWED_NAMES)})")
    module, attr = ALLOWED_NAMES[short]
    return getattr(importlib.import_module(module), attr)


def _value(node: ast.AST) -> Any:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, str, bool,
                                                                    type(None))):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _value(node.operand)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"unsupported expression {ast.unparse(node)!r}")
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_value(e) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict):
        if any(k is None for k in node.keys):
            raise ValueError("'**' is not supported")
        return {_value(k): _value(v)  # type: ignore[arg-type]  # keys checked non-None above
                for k, v in zip(node.keys, node.values, strict=True)}
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict":
        if node.args or any(k.arg is None for k in node.keywords):
            raise ValueError("dict(...) takes keyword arguments only")
        return {k.arg: _value(k.value) for k in node.keywords}
    if isinstance(node, (ast.Name, ast.Attribute)):
        return resolve_name(_dotted(node))
    raise ValueError(f"unsupported expression {ast.unparse(node)!r}")


def parse_expression(text: str) -> Any:
    """Value of a zoo expression string from the restricted grammar (module doc); ValueError
    for anything else (calls other than ``dict``, attributes outside the allow-list, ...)."""
    if not isinstance(text, str):
        raise TypeError(f"expected a string (got {type(text).__name__})")
    if len(text) > 10_000:
        raise ValueError("expression longer than 10000 characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ValueError(f"cannot parse {text!r}: {exc.msg}") from None
    return _value(tree.body)


def policy_kwargs_from(value: Any) -> dict[str, Any]:
    """``policy_kwargs`` of a hyper-parameter entry as keywords: a zoo string
    (:func:`parse_expression`) or a mapping whose ``activation_fn`` / ``optimizer_class`` may be
    names (``nn.Tanh``, ``tanh``). ValueError if it is neither or names something not allowed."""
    if isinstance(value, str):
        value = parse_expression(value)
    if not isinstance(value, dict):
        raise ValueError(f"policy_kwargs must be a mapping or a 'dict(...)' string "
                         f"(got {value!r})")
    out = dict(value)
    for key in ("activation_fn", "optimizer_class"):
        if isinstance(out.get(key), str):
            out[key] = resolve_name(out[key])
    net_arch = out.get("net_arch")
    if net_arch is not None and not isinstance(net_arch, (list, dict)):
        raise ValueError(f"policy_kwargs.net_arch must be a list or a mapping (got {net_arch!r})")
    return out


def normalize_from(value: Any) -> dict[str, Any] | None:
    """VecNormalize keywords from ``normalize`` (false, true, a mapping or a zoo string such as
    ``"{'norm_obs': True, 'norm_reward': False}"``); None if normalisation is off."""
    if isinstance(value, str):
        value = parse_expression(value)
    if value is False or value is None:
        return None
    if value is True:
        return {}
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return dict(value)
    raise ValueError(f"normalize must be true, false or a mapping (got {value!r})")


class _ZooLoader(yaml.SafeLoader):
    """SafeLoader plus the zoo's ``OrderedDict`` tag (as a plain dict)."""


def _ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict[Any, Any]:
    def bad(what: str) -> yaml.constructor.ConstructorError:
        return yaml.constructor.ConstructorError(None, None, f"OrderedDict: {what}",
                                                 node.start_mark)

    # the zoo's form: a sequence holding one sequence of [key, value] pairs
    if not (isinstance(node, yaml.SequenceNode) and len(node.value) == 1
            and isinstance(node.value[0], yaml.SequenceNode)):
        raise bad("expected a sequence holding one list of [key, value] pairs")
    out: dict[Any, Any] = {}
    for pair in node.value[0].value:
        if not (isinstance(pair, yaml.SequenceNode) and len(pair.value) == 2
                and isinstance(pair.value[0], yaml.ScalarNode)):
            raise bad("every item must be a [key, value] pair with a plain key")
        key = loader.construct_object(pair.value[0], deep=True)
        if not isinstance(key, (str, int, float, bool)) or key in out:
            raise bad(f"bad or repeated key {str(key)[:80]!r}")
        out[key] = loader.construct_object(pair.value[1], deep=True)
    return out


_ZooLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict",
                           _ordered_dict)


def zoo_yaml_load(text: str, source: str = "YAML") -> Any:
    """Parse YAML written by the zoo (``OrderedDict`` tags allowed, no other Python tag), with
    the bounds of :func:`softhand_env.physics.safe_yaml.load_bounded` (size, no aliases,
    depth, integer length); ``ValueError`` (one line naming ``source``) otherwise."""
    from softhand_env.physics.safe_yaml import load_bounded

    return load_bounded(text, _ZooLoader, source)


class _NoAliasDumper(yaml.Dumper):
    """``yaml.Dumper`` that writes a repeated object again instead of an anchor and alias
    (the loader refuses aliases)."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def zoo_yaml_dump(mapping: dict[str, Any], path: Path) -> None:
    """Write ``mapping`` (plain YAML values) as the zoo does: an ``OrderedDict`` sorted by key."""
    from collections import OrderedDict

    ordered = OrderedDict((k, mapping[k]) for k in sorted(mapping))
    path.write_text(yaml.dump(ordered, Dumper=_NoAliasDumper))
