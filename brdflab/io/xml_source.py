"""The text of an XML file as it was read, mapped node by node onto its parsed tree.

A save patches the document's current values into a copy of that tree (a `Draft`) and
writes it back through this map: every node, attribute, text and bit of spacing that
did not change is copied from the original text (its quotes, character references,
number spellings, comments, declaration and DOCTYPE line), and only what changed is
spelled anew. A file the map cannot follow (namespaces, an encoding that does not
survive a round trip) is written by lxml instead: the same content, not the same bytes.
Either way the file keeps its encoding, its byte-order mark and its line ends, so that
the lab reads its own save back.
"""

from __future__ import annotations

import codecs
import copy
import re
from dataclasses import dataclass, field

from lxml import etree

_TOKEN = re.compile(r"""
    (?P<comment><!--.*?-->)
  | (?P<cdata><!\[CDATA\[.*?\]\]>)
  | (?P<pi><\?.*?\?>)
  | (?P<doctype><!DOCTYPE[^>]*>)
  | (?P<end></[^>]*>)
  | (?P<start><(?P<name>[^\s/>!?][^\s/>]*)(?:\s+[^\s=/>]+\s*=\s*(?:"[^"]*"|'[^']*'))*\s*/?>)
  | (?P<text>[^<]+)
""", re.S | re.X)
_ATTR = re.compile(r"""(\s+)([^\s=/>]+)(\s*=\s*)(["'])(.*?)\4""", re.S)
_TAG_CLOSE = re.compile(r"\s*/?>\Z")
# byte-order marks, UTF-32 before UTF-16 (FF FE 00 00 starts with FF FE), and the codec each
# fixes: a BOM outranks what the parser reports (libxml2 says UTF-8 for a UTF-16LE file with
# a BOM and no declaration, and "UTF-16" for either byte order)
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32-le"), (codecs.BOM_UTF32_BE, "utf-32-be"), (codecs.BOM_UTF8, "utf-8"),
         (codecs.BOM_UTF16_LE, "utf-16-le"), (codecs.BOM_UTF16_BE, "utf-16-be"))


@dataclass
class _Span:
    """Where one node of the tree lies in the text, and the values it was parsed to."""

    kind: str  # "start" (an element), "comment" or "pi"
    name: str
    start: int
    tag_end: int  # end of the start tag (the whole node for comments and PIs)
    empty: bool = False  # written as <tag .../>
    text_end: int = 0  # end of the text right after the start tag
    end_tag: int = 0  # start of the end tag
    end: int = 0  # end of the node
    tail_end: int = 0  # end of the text after the node
    text: str | None = None
    tail: str | None = None
    attrib: list = field(default_factory=list)  # parsed (name, value) pairs, in order


class _Unmappable(Exception):
    """The text does not follow the shape this map understands."""


class SourceXML:
    """One file's text with the span of every node of `root` in it (mapped at the first
    save, so that reading a file costs no more than parsing it)."""

    def __init__(self, data: bytes, root: etree._Element) -> None:
        self.root = root  # the parsed tree; never modified
        self.encoding = root.getroottree().docinfo.encoding or "UTF-8"  # as the declaration names it
        self.bom, self.codec = codec_of(data, self.encoding)
        self._data: bytes | None = data[len(self.bom):]
        self.text = ""
        self._spans: list[_Span] | None = None
        self.prolog_end = self.epilogue_start = 0

    @property
    def spans(self) -> list[_Span] | None:
        """Every node's span, in document order; None for a text this map cannot follow."""
        if self._data is not None:
            data, self._data = self._data, None
            try:
                self.text = data.decode(self.codec)
                if self.text.encode(self.codec) != data:
                    raise _Unmappable("the encoding does not round-trip")
                self._spans, self.prolog_end, self.epilogue_start = _map(self.text, self.root)
            except (_Unmappable, LookupError, UnicodeError):
                self._spans = None
        return self._spans

    @property
    def mappable(self) -> bool:
        return self.spans is not None

    def draft(self, doctype: str | None) -> "Draft":
        return Draft(self, doctype)

    def encode(self, text: str) -> bytes:
        """`text` as this file's bytes: its BOM, then its encoding (characters it cannot
        hold as character references)."""
        return self.bom + text.encode(self.codec, "xmlcharrefreplace")

    def decode(self, data: bytes) -> str:
        """The text of bytes written by `encode`."""
        return data[len(self.bom):].decode(self.codec) if data.startswith(self.bom) else data.decode(self.codec)


def codec_of(data: bytes, declared: str) -> tuple[bytes, str]:
    """The BOM a file's bytes start with and the Python codec of the rest (`declared`: the
    encoding the parser reports)."""
    return next(((bom, codec) for bom, codec in _BOMS if data.startswith(bom)),
                (b"", _byte_order_free(declared, data)))


def _byte_order_free(encoding: str, data: bytes) -> str:
    """The codec for a file without a BOM: a bare "UTF-16"/"UTF-32" would write Python's own BOM
    and byte order, so the byte order is the one the file's first character ('<') shows."""
    width = {"UTF-16": 2, "UTF-32": 4}.get(encoding.upper().replace("_", "-"))
    if width is None:
        return encoding
    return f"utf-{8 * width}-{'le' if data[:1] == b'<' else 'be'}"


class Draft:
    """A copy of a source's tree to patch, which writes back unchanged parts verbatim."""

    def __init__(self, source: SourceXML, doctype: str | None) -> None:
        self.source = source
        self.doctype = doctype
        self.root = copy.deepcopy(source.root)
        pairs = list(zip(source.root.iter(), self.root.iter()))
        self._working = dict(pairs)  # original node -> its copy here
        self._index = {w: i for i, (_, w) in enumerate(pairs)}  # copy -> its span
        self._spans = source.spans  # the first call decodes and maps the text
        # new text gets the file's line ends (the parser reads CR LF and CR as LF)
        text = source.text
        self._newline = "\r\n" if "\r\n" in text else "\r" if "\r" in text else "\n"

    def own(self, original: etree._Element | None) -> etree._Element | None:
        """The copy in this draft of a node of the source tree (None for other nodes)."""
        return None if original is None else self._working.get(original)

    def is_original(self, node: etree._Element) -> bool:
        return node in self._index

    def to_bytes(self) -> bytes:
        src = self.source
        if src.mappable:
            out = [src.text[:src.prolog_end]]
            try:
                self._emit(self.root, out)
            except _Unmappable:
                pass
            else:
                out.append(src.text[src.epilogue_start:])
                return src.encode("".join(out))
        doctype = f"<!DOCTYPE {self.doctype}>\n" if self.doctype else ""
        declared = src.encoding if not src.bom else src.codec.upper()[:6].rstrip("-")  # UTF-8, UTF-16, UTF-32
        text = f"<?xml version='1.0' encoding='{declared}'?>\n{doctype}" + etree.tostring(self.root, encoding=str) + "\n"
        return src.encode(text.replace("\n", self._newline))

    # --- writing -----------------------------------------------------------------------
    def _span(self, node) -> _Span | None:
        i = self._index.get(node)
        return None if i is None else self._spans[i]

    def _emit(self, node, out: list[str]) -> None:
        text = self.source.text
        span = self._span(node)
        if not isinstance(node.tag, str):  # a comment or a processing instruction
            if span is not None and node.text == span.text:
                out.append(text[span.start:span.end])
            else:
                out.append(etree.tostring(node, encoding=str, with_tail=False))
            return
        if span is not None and span.name != node.tag:
            span = None
        has_content = bool(node.text) or len(node) > 0
        if span is None:
            out.append("<" + node.tag + "".join(f' {k}="{_attr_text(v, chr(34))}"' for k, v in node.attrib.items()))
            out.append(">" if has_content else "/>")
        else:
            out.append(self._start_tag(node, span, has_content))
            if span.empty and not has_content:
                return
        if span is not None and node.text == span.text:
            out.append(text[span.tag_end:span.text_end])
        elif node.text:
            out.append(self._new_text(node.text))
        for child in node:
            self._emit(child, out)
            child_span = self._span(child)
            if child_span is not None and child.tail == child_span.tail:
                out.append(text[child_span.end:child_span.tail_end])
            elif child.tail:
                out.append(self._new_text(child.tail))
        if span is None or span.empty:
            if has_content:
                out.append(f"</{node.tag}>")
        else:
            out.append(text[span.end_tag:span.end])

    def _new_text(self, value: str) -> str:
        return _text(value).replace("\n", self._newline)

    def _start_tag(self, node, span: _Span, has_content: bool) -> str:
        text = self.source.text
        items = node.attrib.items()
        tag = text[span.start:span.tag_end]
        if items == span.attrib and not (span.empty and has_content):
            return tag
        close = _TAG_CLOSE.search(tag).start()
        if items == span.attrib:
            head = tag[:close]
        else:
            attrs = [(a.group(2), a.start(), a.end(), a.group(4)) for a in _ATTR.finditer(tag, len(span.name) + 1, close)]
            if [a[0] for a in attrs] != [k for k, _ in span.attrib]:
                raise _Unmappable(f"the attributes of <{span.name}> do not match the text")
            parts = [tag[:attrs[0][1] if attrs else close]]
            old = dict(span.attrib)
            for name, a_start, a_end, quote in attrs:
                if name not in node.attrib:
                    continue
                value = node.get(name)
                if value == old[name]:
                    parts.append(tag[a_start:a_end])
                else:
                    raw = tag[a_start:a_end]
                    prefix = raw[: raw.index(quote) + 1]
                    parts.append(prefix + _attr_text(value, quote) + quote)
            parts += [f' {k}="{_attr_text(v, chr(34))}"' for k, v in items if k not in old]
            head = "".join(parts)
        closing = tag[close:]
        if span.empty and has_content:
            closing = closing[: closing.rindex("/")] + ">"
        return head + closing


def _text(value: str) -> str:
    return value.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("\r", "&#13;")


def _attr_text(value: str, quote: str) -> str:
    out = value.replace("&", "&amp;").replace("<", "&lt;").replace("\n", "&#10;").replace("\r", "&#13;")
    out = out.replace("\t", "&#9;")
    return out.replace('"', "&quot;") if quote == '"' else out.replace("'", "&apos;")


# --- mapping ----------------------------------------------------------------------------

def _map(text: str, root: etree._Element) -> tuple[list[_Span], int, int]:
    """Every node of `root` (document order) with its span, and where the root begins and ends."""
    spans: list[_Span] = []
    stack: list[_Span] = []
    owner: tuple[_Span, str] | None = None  # whose text or tail the next text belongs to
    prolog_end = epilogue_start = None
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise _Unmappable(f"unexpected text at {pos}")
        kind, pos = m.lastgroup, m.end()
        if kind in ("text", "cdata"):
            if owner is not None:
                span, which = owner
                setattr(span, "text_end" if which == "text" else "tail_end", pos)
            elif kind == "cdata" or m.group().strip():
                raise _Unmappable("text outside the root element")
            continue
        inside = prolog_end is not None and epilogue_start is None
        if not inside:
            if kind == "start" and prolog_end is None:
                prolog_end = m.start()
            elif kind in ("comment", "pi", "doctype"):
                continue
            else:
                raise _Unmappable(f"{kind} outside the root element")
        if kind in ("comment", "pi"):
            span = _Span(kind, "", m.start(), pos, end=pos, tail_end=pos)
            spans.append(span)
            owner = (span, "tail")
        elif kind == "start":
            span = _element_span(m)
            spans.append(span)
            if span.empty:
                owner = (span, "tail")
                if not stack:
                    epilogue_start, owner = pos, None
            else:
                stack.append(span)
                owner = (span, "text")
        elif kind == "end":
            if not stack:
                raise _Unmappable("an end tag without a start")
            span = stack.pop()
            span.end_tag, span.end, span.tail_end = m.start(), pos, pos
            owner = (span, "tail")
            if not stack:
                epilogue_start, owner = pos, None
        else:
            raise _Unmappable(f"{kind} inside the root element")
    if prolog_end is None or epilogue_start is None:
        raise _Unmappable("no complete root element")
    _check_against(spans, root)
    return spans, prolog_end, epilogue_start


def _element_span(m: re.Match) -> _Span:
    end = m.end()
    empty = m.group().endswith("/>")
    return _Span("start", m.group("name"), m.start(), end, empty, text_end=end, end=end if empty else 0, tail_end=end)


def _check_against(spans: list[_Span], root: etree._Element) -> None:
    """Each span is the node of the tree at its place (an element's attributes are checked
    against its tag when they are rewritten)."""
    count = 0
    for count, (node, span) in enumerate(zip(root.iter(), spans), 1):
        if isinstance(node.tag, str):
            if span.kind != "start" or span.name != node.tag or "{" in node.tag:
                raise _Unmappable(f"<{node.tag}> does not match the text")
            span.attrib = node.attrib.items()
        elif span.kind != ("comment" if isinstance(node, etree._Comment) else "pi"):
            raise _Unmappable("a comment or processing instruction does not match the text")
        span.text, span.tail = node.text, node.tail
    if count != len(spans) or sum(1 for _ in root.iter()) != count:
        raise _Unmappable("the text and the tree differ in their number of nodes")
