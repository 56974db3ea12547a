"""Reading the study's YAML files (scene, design, plans) with one clear error."""

from __future__ import annotations

from pathlib import Path

from sim.study.design.errors import DesignError

__all__ = ["read_yaml"]


def read_yaml(path: Path, what: str) -> object:
    """The data in `path`; DesignError names `what` it is, the file and the problem."""
    import yaml

    try:
        return yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as error:
        raise DesignError(f"cannot read {what} {path}: {error.strerror}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise DesignError(f"{what} {path} is not valid YAML: {error}".replace("\n", " ")) from None
