"""Configuration files: YAML read strictly (a key given twice is an error) and pydantic errors turned into a
``ConfigError`` that names the field's YAML path and its allowed range (the range and unit come from the field's
constraints and description). Used for the settings profiles, the mission tables and the ground station's section.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from app.errors import ConfigError

ModelT = TypeVar("ModelT", bound=BaseModel)


def format_validation_error(source: str, exc: ValidationError, model: type[BaseModel]) -> ConfigError:
    """The first error of ``exc`` as a ``ConfigError`` naming the YAML path and the allowed range."""
    err = exc.errors()[0]
    path = ".".join(str(p) for p in err["loc"])
    got = err.get("input")
    message = err["msg"]
    allowed = _allowed_range(model, [str(p) for p in err["loc"]])
    if err["type"] == "extra_forbidden":
        known = _known_fields(model, [str(p) for p in err["loc"][:-1]])
        message = "unknown field" + (f"; known fields: {', '.join(known)}" if known else "")
    else:
        message = f"{message} (got {got!r})"
        if allowed:
            message += f"; allowed {allowed}"
    return ConfigError(source, path, message)


def _field_info(model: type[BaseModel], loc: list[str]) -> Any:
    current: Any = model
    info = None
    for key in loc:
        fields = getattr(current, "model_fields", None)
        if not fields or key not in fields:
            return None
        info = fields[key]
        current = info.annotation
    return info


def _known_fields(model: type[BaseModel], loc: list[str]) -> list[str]:
    current: Any = model
    for key in loc:
        fields = getattr(current, "model_fields", None)
        if not fields or key not in fields:
            return []
        current = fields[key].annotation
    return sorted(getattr(current, "model_fields", {}))


def _allowed_range(model: type[BaseModel], loc: list[str]) -> str:
    info = _field_info(model, loc)
    if info is None:
        return ""
    lo = hi = None
    for m in info.metadata:
        lo = getattr(m, "ge", lo) if getattr(m, "ge", None) is not None else lo
        lo = getattr(m, "gt", lo) if getattr(m, "gt", None) is not None else lo
        hi = getattr(m, "le", hi) if getattr(m, "le", None) is not None else hi
        hi = getattr(m, "lt", hi) if getattr(m, "lt", None) is not None else hi
    if lo is None and hi is None:
        return ""
    unit = ""
    if info.description and "," in info.description:
        unit = " " + info.description.rsplit(",", 1)[1].strip()
    return f"{'' if lo is None else lo}..{'' if hi is None else hi}{unit}"


def validate_section(model: type[ModelT], data: dict[str, Any], source: str) -> ModelT:
    """One settings section from a mapping; raises ``ConfigError`` naming the field and its allowed range."""
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise format_validation_error(source, e, model) from e


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, path: str, line: int, first_line: int) -> None:
        super().__init__(path)
        self.path, self.line, self.first_line = path, line, first_line


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that refuses a mapping key given twice (plain YAML keeps the last one silently)."""

    def construct_document(self, node: yaml.Node) -> Any:
        _check_duplicates(node, "")
        return super().construct_document(node)


def _check_duplicates(node: yaml.Node, path: str) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict[Any, int] = {}
        for key_node, value_node in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else id(key_node)
            child = f"{path}.{key}" if path else str(key)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise _DuplicateKey(child, line, seen[key])
            seen[key] = line
            _check_duplicates(value_node, child)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _check_duplicates(item, f"{path}[{i}]")


def load_yaml(path: Path) -> dict[str, Any]:
    """A YAML mapping from ``path``; a duplicate key (at any depth) is an error naming its path and lines."""
    try:
        data = yaml.load(path.read_text(), Loader=_StrictLoader) or {}
    except FileNotFoundError as e:
        raise ConfigError(str(path), "", "file not found") from e
    except OSError as e:
        raise ConfigError(str(path), "", f"cannot read: {e.strerror or e}") from e
    except _DuplicateKey as e:
        raise ConfigError(str(path), e.path, f"duplicate key (line {e.line}, first at line {e.first_line})") from e
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise ConfigError(str(path), "", f"not valid YAML: {e}") from e
    if not isinstance(data, dict):
        raise ConfigError(str(path), "", "top level must be a mapping")
    return data
