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
import re
import xml.parsers.expat
from pathlib import Path

from hybrid_force.errors import URDFError

__all__ = ["urdf_text"]

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
        URDFError: the file is missing, a directory, unreadable, not decodable, or not
            well-formed XML (the parser's reason, line and column).
    """
    path = Path(path)
    if not path.exists():
        raise URDFError(f"URDF file not found: {path}")
    if not path.is_file():
        raise URDFError(f"URDF path is not a file: {path}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise URDFError(f"cannot read URDF {path}: {exc}") from exc
    scan = _PrefixScan()
    try:
        scan.parse(raw)
    except xml.parsers.expat.ExpatError as exc:  # the same text ElementTree's ParseError has
        raise URDFError(f"malformed URDF {path}: XML parse error: {exc}") from None
    encoding = scan.encoding or "utf-8"
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding = "utf-16"
    elif codecs.lookup(encoding).name == "utf-8":
        encoding = "utf-8-sig"  # drops a byte-order mark
    try:
        text = raw.decode(encoding)
        root_at = len(raw[: scan.root_byte].decode(encoding))
    except (LookupError, UnicodeDecodeError) as exc:
        raise URDFError(f"cannot decode URDF {path} as {encoding}: {exc}") from None
    if scan.undeclared:
        end = root_at + 1 + len(scan.root_name)
        if text[root_at:end] != "<" + scan.root_name:  # never seen; refuse rather than guess
            raise URDFError(f"cannot locate the root element <{scan.root_name}> in {path}")
        declarations = "".join(
            f' xmlns:{prefix}="{_UNDECLARED_NS}{prefix}"' for prefix in scan.undeclared
        )
        text = text[:end] + declarations + text[end:]
    if scan.encoding and codecs.lookup(scan.encoding).name != "utf-8":
        text = _XML_DECL_ENCODING.sub(r"\1\2UTF-8\2", text, count=1)
    return text


class _PrefixScan:
    """One pass of expat without namespace processing over the raw bytes: the declared
    encoding, the root element's name and byte offset, and the prefixes used out of scope."""

    def __init__(self) -> None:
        self.encoding: str | None = None
        self.root_name = ""
        self.root_byte = 0
        self.undeclared: list[str] = []
        self._scopes: list[frozenset[str]] = [frozenset({"xml", "xmlns"})]
        self._parser = xml.parsers.expat.ParserCreate()
        self._parser.XmlDeclHandler = self._declaration
        self._parser.StartElementHandler = self._start
        self._parser.EndElementHandler = self._end

    def parse(self, raw: bytes) -> None:
        self._parser.Parse(raw, True)

    def _declaration(self, version: str, encoding: str | None, standalone: int) -> None:
        self.encoding = encoding

    def _start(self, name: str, attributes: dict[str, str]) -> None:
        if not self.root_name:
            self.root_name, self.root_byte = name, self._parser.CurrentByteIndex
        declared = {key[6:] for key in attributes if key.startswith("xmlns:")}
        scope = self._scopes[-1] | declared
        self._scopes.append(scope)
        for qualified in (name, *attributes):
            prefix, colon, _ = qualified.partition(":")
            if colon and prefix not in scope and prefix not in self.undeclared:
                self.undeclared.append(prefix)

    def _end(self, name: str) -> None:
        self._scopes.pop()
