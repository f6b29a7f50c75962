"""Reading a URDF file as XML text that every parser of the toolkit accepts.

The file is read once and made acceptable to every XML parser the toolkit uses (Python's
ElementTree, Pinocchio's urdfdom/TinyXML2, yourdfpy's lxml).
Extension tags that URDF tools ignore (``<gazebo>``, ``<transmission>``, ``<ros2_control>``,
Drake's ``<drake:...>`` elements) are left in place: every reader looks only at the direct
``<link>`` and ``<joint>`` children of ``<robot>``. An element or attribute whose namespace
prefix the file never declares (``<link name="a" drake:foo="1">`` without ``xmlns:drake``)
makes namespace-aware parsers refuse the whole file ("unbound prefix"); such prefixes are
declared on the root element (``xmlns:drake="urn:hybrid-force:undeclared-prefix:drake"``),
which changes no URDF element and no line number.
:func:`hybrid_force.model.urdf_check.check_urdf` reads the same text.
"""

from __future__ import annotations

import codecs
import contextlib
import re
import xml.parsers.expat
from pathlib import Path

from hybrid_force.errors import RobotError

__all__ = [
    "MAX_ELEMENTS",
    "MAX_JOINTS",
    "MAX_MODEL_BYTES",
    "MAX_XML_DEPTH",
    "check_file_size",
    "check_model_size",
    "urdf_text",
]

MAX_JOINTS = 100
"""The most moving joints a model may have (a URDF ``<joint>`` of any type but ``fixed``;
every ``<joint>`` of an MJCF file): Pinocchio's model data take memory ∝ nv³ (70 MB at 100
joints, 500 MB at 200). The largest bundled model, g1, has 29 (docs/robots.md)."""

MAX_ELEMENTS = 1000
"""The most ``<joint>`` elements of any type, and the most links (URDF ``<link>``, MJCF
``<body>``): Pinocchio's URDF parser recurses once per joint, fixed ones included (5,000
crash it); fixed joints are otherwise cheap (frames). Both are counted before any model
parser runs."""

MAX_MODEL_BYTES = 16 * 2**20
"""The largest model file (and xacro expansion) read, 16 MiB: the largest bundled URDF is
36 kB."""

MAX_XML_DEPTH = 256
"""The deepest nesting of XML elements in a model file (an MJCF chain nests one ``<body>`` per
link; a URDF nests a few levels)."""

# The namespace an undeclared prefix is bound to (any URI does; this one says what happened).
_UNDECLARED_NS = "urn:hybrid-force:undeclared-prefix:"
_XML_DECL_ENCODING = re.compile(r"""^(\ufeff?<\?xml[^>]*?\bencoding\s*=\s*)(["'])[^"']*\2""")


def urdf_text(path: Path | str) -> str:
    """The URDF file at ``path`` as XML text that every parser of the toolkit accepts.

    The file's text, decoded (its declared encoding, UTF-8 by default), with every namespace
    prefix that it uses without declaring it declared on the root element (see the module
    docstring); an XML declaration naming another encoding than UTF-8 then says UTF-8. Feed
    the result to ``xml.etree.ElementTree.fromstring``, ``pinocchio.buildModelFromXML`` or
    :func:`check_urdf` (``text=``). Only well-formedness is checked here.

    Args:
        path: path of a ``.urdf`` file.

    Returns:
        the sanitised XML text (same lines as the file).

    Raises:
        RobotError: the file is missing, a directory, unreadable, not decodable, or not
            well-formed XML (the parser's reason, line and column).
    """
    path = Path(path)
    if not path.exists():
        raise RobotError(f"URDF file not found: {path}")
    if not path.is_file():
        raise RobotError(f"URDF path is not a file: {path}")
    try:
        check_file_size(path, "URDF")
        raw = path.read_bytes()
    except OSError as exc:
        raise RobotError(f"cannot read URDF {path}: {exc}") from exc
    scan = _PrefixScan(f"URDF {path}", "urdf")
    try:
        scan.parse(raw)
    except xml.parsers.expat.ExpatError as exc:  # the same text ElementTree's ParseError has
        raise RobotError(f"malformed URDF {path}: XML parse error: {exc}") from None
    encoding = scan.encoding or "utf-8"
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding = "utf-16"
    elif codecs.lookup(encoding).name == "utf-8":
        encoding = "utf-8-sig"  # drops a byte-order mark
    try:
        text = raw.decode(encoding)
        root_at = len(raw[: scan.root_byte].decode(encoding))
    except (LookupError, UnicodeDecodeError) as exc:
        raise RobotError(f"cannot decode URDF {path} as {encoding}: {exc}") from None
    if scan.undeclared:
        end = root_at + 1 + len(scan.root_name)
        if text[root_at:end] != "<" + scan.root_name:  # never seen; refuse rather than guess
            raise RobotError(f"cannot locate the root element <{scan.root_name}> in {path}")
        declarations = "".join(
            f' xmlns:{prefix}="{_UNDECLARED_NS}{prefix}"' for prefix in scan.undeclared
        )
        text = text[:end] + declarations + text[end:]
    if scan.encoding and codecs.lookup(scan.encoding).name != "utf-8":
        text = _XML_DECL_ENCODING.sub(r"\1\2UTF-8\2", text, count=1)
    return text


def check_model_size(source: str, data: bytes | str, kind: str) -> None:
    """Refuse a model text beyond :data:`MAX_MODEL_BYTES`, :data:`MAX_JOINTS` or
    :data:`MAX_XML_DEPTH` in one streaming pass of expat (no tree is built, no recursion).

    Args:
        source: how messages name the model (its file).
        data: the model's text or raw bytes.
        kind: ``"urdf"`` (counts the ``<joint>``/``<link>`` children of the root) or
            ``"mjcf"`` (every ``<joint>``/``<freejoint>`` and ``<body>``).

    Raises:
        RobotError: naming ``source``, the count and the maximum. Malformed XML is not refused
            here: the parser that follows says where.
    """
    size = len(data.encode("utf-8")) if isinstance(data, str) else len(data)
    if size > MAX_MODEL_BYTES:
        raise RobotError(_too_large(source, size))
    with contextlib.suppress(xml.parsers.expat.ExpatError):
        _PrefixScan(source, kind).parse(data)


def _too_large(source: str, size: int) -> str:
    return (
        f"{source} is {size} bytes, more than the {MAX_MODEL_BYTES} a model file may have "
        "(MAX_MODEL_BYTES, docs/robots.md)"
    )


def check_file_size(path: Path, label: str) -> None:
    """RobotError before a file beyond :data:`MAX_MODEL_BYTES` is read (an OSError of stat
    propagates: the caller says why the file cannot be read)."""
    size = path.stat().st_size
    if size > MAX_MODEL_BYTES:
        raise RobotError(_too_large(f"{label} {path}", size))


class _PrefixScan:
    """One pass of expat without namespace processing over the raw bytes: the declared
    encoding, the root element's name and byte offset, and the prefixes used out of scope;
    on the way, the model's size against :data:`MAX_JOINTS` and :data:`MAX_XML_DEPTH` (a
    RobotError from a handler stops expat at once)."""

    def __init__(self, source: str, kind: str) -> None:
        self.source, self.kind = source, kind
        self.joints = self.moving = self.links = 0
        self.encoding: str | None = None
        self.root_name = ""
        self.root_byte = 0
        self.undeclared: list[str] = []
        self._scopes: list[frozenset[str]] = [frozenset({"xml", "xmlns"})]
        self._parser = xml.parsers.expat.ParserCreate()
        self._parser.XmlDeclHandler = self._declaration
        self._parser.StartElementHandler = self._start
        self._parser.EndElementHandler = self._end

    def parse(self, raw: bytes | str) -> None:
        self._parser.Parse(raw, True)

    def _declaration(self, version: str, encoding: str | None, standalone: int) -> None:
        self.encoding = encoding

    def _start(self, name: str, attributes: dict[str, str]) -> None:
        if not self.root_name:
            self.root_name, self.root_byte = name, self._parser.CurrentByteIndex
        self._count(name, len(self._scopes), attributes)
        declared = {key[6:] for key in attributes if key.startswith("xmlns:")}
        scope = self._scopes[-1] | declared
        self._scopes.append(scope)
        for qualified in (name, *attributes):
            prefix, colon, _ = qualified.partition(":")
            if colon and prefix not in scope and prefix not in self.undeclared:
                self.undeclared.append(prefix)

    def _end(self, name: str) -> None:
        self._scopes.pop()

    def _count(self, name: str, depth: int, attributes: dict[str, str]) -> None:
        """Count ``name`` (at ``depth``, the root at 1); refuse beyond the maximums."""
        if depth > MAX_XML_DEPTH:
            raise RobotError(
                f"{self.source}: elements nest more than {MAX_XML_DEPTH} deep (at <{name}>, "
                f"line {self._parser.CurrentLineNumber}): MAX_XML_DEPTH, docs/robots.md"
            )
        if self.kind == "urdf":
            joint, link = depth == 2 and name == "joint", depth == 2 and name == "link"
            moving = joint and attributes.get("type") != "fixed"
        else:
            joint, link = name in ("joint", "freejoint"), name == "body"
            moving = joint
        self.joints += joint
        self.moving += moving
        self.links += link
        line = self._parser.CurrentLineNumber
        if self.moving > MAX_JOINTS:
            raise RobotError(
                f"{self.source} has more than {MAX_JOINTS} moving joints (line {line}): a model "
                f"may have at most MAX_JOINTS = {MAX_JOINTS} (docs/robots.md)"
            )
        if self.joints > MAX_ELEMENTS or self.links > MAX_ELEMENTS:
            what = "joints" if self.joints > MAX_ELEMENTS else "links or bodies"
            raise RobotError(
                f"{self.source} has more than {MAX_ELEMENTS} {what} (line {line}): a model may "
                f"have at most MAX_ELEMENTS = {MAX_ELEMENTS} of each, fixed joints included "
                "(docs/robots.md)"
            )
