"""Reading a data file from disk: size limit, encoding, YAML or JSON by its name."""

from __future__ import annotations

from pathlib import Path

from datafile.errors import DataFileError
from datafile.field import Field
from datafile.json_text import parse_json
from datafile.nodes import Node
from datafile.yaml_text import parse_yaml

__all__ = ["MAX_BYTES", "load_file", "parse_text", "read_text", "shipped_or_path"]

#: Larger files are refused before parsing: Caretaker's data files are a few kilobytes, and a
#: huge one is a mistake (or an attack) that would otherwise hold a loader for minutes.
MAX_BYTES = 2 * 1024 * 1024


def read_text(path: Path, error: type[DataFileError] = DataFileError) -> str:
    """The file's text, UTF-8 (a BOM is allowed).

    Raises:
        error: unreadable, larger than :data:`MAX_BYTES`, or not UTF-8 (naming the line).
    """
    try:
        with path.open("rb") as handle:
            raw = handle.read(MAX_BYTES + 1)
    except OSError as exc:
        raise error(path, 0, "", f"cannot read: {exc.strerror or exc}") from None
    if len(raw) > MAX_BYTES:
        raise error(path, 0, "", f"larger than {MAX_BYTES // (1024 * 1024)} MiB; a data file this size is a mistake")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error(
            path, line, "", f"not UTF-8 text: byte 0x{raw[exc.start]:02x} cannot start a character", column=column
        ) from None


def parse_text(text: str, path: Path, *, json: bool, error: type[DataFileError] = DataFileError) -> Node:
    """``text`` parsed as JSON or YAML, errors raised as ``error``."""
    try:
        return parse_json(text, str(path)) if json else parse_yaml(text, str(path))
    except DataFileError as exc:
        if type(exc) is error:
            raise
        raise error(exc.path, exc.line, exc.key, exc.problem, column=exc.column) from None


def load_file(path: str | Path, *, error: type[DataFileError] = DataFileError, json: bool | None = None) -> Field:
    """Read and parse a data file; its root value as a :class:`Field`.

    JSON when the name ends in ``.json`` (unless ``json`` says otherwise), YAML otherwise.
    """
    path = Path(path)
    is_json = path.suffix.lower() == ".json" if json is None else json
    return Field(parse_text(read_text(path, error), path, json=is_json, error=error), path, "", error)


def shipped_or_path(
    name_or_path: str | Path, shipped: Path, what: str, error: type[DataFileError] = DataFileError
) -> Path:
    """``name_or_path`` as a file path, or, when it is a bare name (``iva``), the YAML file of
    that name in the ``shipped`` folder.

    Raises:
        error: a bare name with no such file in ``shipped``; the message lists the names there.
    """
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.parent != Path("."):
        return path
    candidate = shipped / f"{name_or_path}.yaml"
    if not candidate.is_file():
        known = sorted(p.stem for p in shipped.glob("*.yaml"))
        raise error(str(name_or_path), 0, "", f"no such {what}; give a {what} file or one of {', '.join(known)}")
    return candidate
