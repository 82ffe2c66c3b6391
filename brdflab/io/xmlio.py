"""BRDFLab (2009) XML materials: read and write, losslessly and safely.

Layout (../shared/CONVENTIONS.md): <BRDF> holds an <Info>, one <Material> and any
number of <Fitting>s. Unknown elements are reported as warnings and kept. A document
read from a file keeps that file's text and tree (`BRDFDocument.source`): saving writes
the current values into them (brdflab.io.xml_update), so that what did not change is
written back byte for byte. Parsing never resolves entities, loads DTDs or touches the
network; saving is atomic.
"""

from __future__ import annotations

import copy
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from brdflab.errors import BRDFLabError
from brdflab.io.atomic import atomic_write
from brdflab.io.bounded import MAX_DATA_BYTES, file_sha256, outside_problem, read_bounded
from brdflab.io.numbers import ascii_integer, ascii_number
from brdflab.io.xml_source import SourceXML, codec_of
from brdflab.material.analytic import MAX_CHANNELS, MAX_LOBES, AnalyticMaterial, Lobe, SourceLinked
from brdflab.models import get_model

ANALYTIC = "Analytic"
MAX_XML_BYTES = 64 << 20  # a 20,000-lobe material is 3 MB
WARNINGS_LISTED = 10  # unknown elements listed one by one; the rest are counted
MAX_ELEMENTS = 1_200_000  # a 100,000-lobe material has 500,000; each kept unknown one costs ~700 bytes
MAX_ATTRIBUTES = 256  # of an element the reader interprets (lxml reads attributes in quadratic time)
SIMULATED_TYPES = ("SCATMECH", "RayBounce")  # <Type> names the simulation library, as BRDFLab does


@dataclass
class MeasuredReference(SourceLinked):
    """A material whose values live in a data file named relative to the XML file."""

    type: str
    name: str  # as written in <Name>
    base_dir: Path | None = None
    sha256: str | None = None
    extra: list = field(default_factory=list)
    source: object | None = field(default=None, compare=False, repr=False)  # its <Material> element

    kind = "Measured"

    @property
    def path(self) -> Path:
        p = Path(self.name)
        return p if p.is_absolute() or self.base_dir is None else self.base_dir / p

    @property
    def missing(self) -> bool:
        return not os.path.isfile(self.path)  # False, not an error, for a name too long for the system

    def current_sha256(self) -> str | None:
        """The data file's checksum; None when it is missing, special or too large to be data."""
        return None if self.missing else file_sha256(self.path, MAX_DATA_BYTES)

    def confinement_problem(self) -> str | None:
        """Why the data file may not be opened, or None (the data-file policy of
        docs/hostile-input.md, `outside_problem`): a hand-made `../../etc/shadow` is refused
        before a byte of it is interpreted; a file that is not there is no problem here."""
        if not os.path.exists(self.path):  # False, not an error, for a name too long for the system
            return None
        return outside_problem(self.path, self.base_dir or Path("."), self.sha256, MAX_DATA_BYTES, "data file")

    def checksum_problem(self) -> str | None:
        """A warning when the data file no longer matches the checksum the material records."""
        if not self.sha256 or self.missing:
            return None
        if self.current_sha256() != self.sha256.strip().lower():
            return f"{self.path}: the data does not match the sha256 checksum recorded in the material"
        return None

    def describe(self) -> dict:
        out = {"type": self.type, "data_file": self.name, "resolved_path": str(self.path), "missing": self.missing}
        if self.sha256:
            out["sha256"] = self.sha256
            if not self.missing:
                out["sha256_matches"] = self.current_sha256() == self.sha256
        return out


@dataclass
class SimulatedReference(SourceLinked):
    """A simulated material as stored: library (<Type>), model, every parameter (as text),
    seed, ray count and table resolution; `brdflab.simulation` rebuilds it."""

    type: str
    name: str
    model: str
    parameters: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)  # seed, samples, resolution (text)
    extra: list = field(default_factory=list)
    source: object | None = field(default=None, compare=False, repr=False)  # its <Material> element

    kind = "Simulated"

    def describe(self) -> dict:
        return {"type": self.type, "name": self.name, "model": self.model,
                "parameters": dict(self.parameters), **self.settings}


@dataclass
class Fitting(SourceLinked):
    """A stored fit: an analytic material plus how it was obtained."""

    material: AnalyticMaterial
    error: float | None = None
    read_only: bool = False
    optimizer: str = "LevenbergMarquardt"
    statistics: dict = field(default_factory=dict)  # metric, seconds, iterations, ...
    attributes: dict = field(default_factory=dict)  # unknown attributes of <Fitting>
    extra: list = field(default_factory=list)
    source: object | None = field(default=None, compare=False, repr=False)  # its <Fitting> element

    def describe(self) -> dict:
        return {
            "error": self.error,
            "readOnly": self.read_only,
            "optimizer": self.optimizer,
            "statistics": dict(self.statistics),
            "material": self.material.describe(),
        }


@dataclass
class BRDFDocument(SourceLinked):
    """Everything one XML file holds."""

    material: AnalyticMaterial | MeasuredReference | SimulatedReference
    fittings: list[Fitting] = field(default_factory=list)
    info: etree._Element | None = None
    extra: list = field(default_factory=list)
    path: Path | None = None
    warnings: list[str] = field(default_factory=list)
    # a model file that is not the one the material was saved with: every command says so
    model_warnings: list[str] = field(default_factory=list)
    doctype: str | None = None  # the name of a bare <!DOCTYPE NAME> line, kept on save
    source: SourceXML | None = field(default=None, compare=False, repr=False)  # the file as read

    def describe(self) -> dict:
        return {
            "file": None if self.path is None else str(self.path),
            "material": self.material.describe(),
            "fittings": [f.describe() for f in self.fittings],
            "warnings": list(self.warnings),
        }


# --------------------------------------------------------------------------------------
# reading

_PARSER_OPTIONS = dict(
    resolve_entities=False, no_network=True, load_dtd=False, dtd_validation=False, huge_tree=False,
    remove_blank_text=False,  # the file's layout is kept for saving it back
)


class _Reader:
    def __init__(self, path: Path | None, base_dir: Path | None) -> None:
        self.path = path
        self.base_dir = base_dir
        self.warnings: list[str] = []
        self.model_warnings: list[str] = []
        self.unknown_count = 0

    def fail(self, el: etree._Element | None, message: str) -> BRDFLabError:
        where = f"line {el.sourceline}: <{el.tag}>: " if el is not None and el.sourceline else ""
        return BRDFLabError(where + message, self.path)

    def unknown(self, el: etree._Element, parent: str) -> None:
        self.unknown_count += 1
        if self.unknown_count <= WARNINGS_LISTED:
            self.warnings.append(f"line {el.sourceline}: unknown element <{el.tag}> in <{parent}> kept as is")

    def summarised_warnings(self) -> list[str]:
        """The warnings, with unknown elements past the first WARNINGS_LISTED counted in one line."""
        more = self.unknown_count - WARNINGS_LISTED
        return self.warnings + ([f"... and {more:,} more"] if more > 0 else [])

    def attributes(self, el: etree._Element) -> dict[str, str]:
        """The attributes of an element the reader interprets; an absurd count is refused."""
        if len(el.attrib) > MAX_ATTRIBUTES:
            raise self.fail(el, f"{len(el.attrib):,} attributes (at most {MAX_ATTRIBUTES})")
        return dict(el.attrib)

    def single(self, el: etree._Element, tag: str) -> etree._Element | None:
        """el's one <tag> child: a second one is refused, as the two could say different things
        and a save would update only the first."""
        found = el.findall(tag)
        if len(found) > 1:
            raise self.fail(found[1], f"a second <{tag}> in <{el.tag}> (the first is on line {found[0].sourceline})")
        return found[0] if found else None

    def text(self, el: etree._Element, tag: str, required: bool = True) -> str | None:
        value = element_text(self.single(el, tag))
        if value is None and required:
            raise self.fail(el, f"missing <{tag}>")
        return value

    def number(self, el: etree._Element, attr: str, value: str) -> float:
        try:
            v = ascii_number(value)
        except ValueError as e:
            raise self.fail(el, f"{attr} is {e}") from None
        if not math.isfinite(v):
            raise self.fail(el, f"{attr} is {value} (must be finite)")
        return v

    def integer(self, el: etree._Element, attr: str) -> int:
        value = el.get(attr)
        if value is None:
            raise self.fail(el, f"missing attribute {attr}")
        try:
            return ascii_integer(value)
        except ValueError as e:
            raise self.fail(el, f"{attr} is {e}") from None

    # --- elements ---------------------------------------------------------------
    def document(self, root: etree._Element) -> BRDFDocument:
        if root.tag != "BRDF":  # its own tag is not named: the file is not a material at all
            raise BRDFLabError(f"line {root.sourceline}: the root element must be <BRDF>", self.path)
        info = None
        material = None
        fittings: list[Fitting] = []
        extra = []
        for child in root:
            if not isinstance(child.tag, str):
                continue  # comments, processing instructions
            if child.tag == "Info" and info is None:
                info = copy.deepcopy(child)
            elif child.tag == "Info":
                self.warnings.append(f"line {child.sourceline}: a second <Info> in <BRDF> kept as is")
                extra.append(copy.deepcopy(child))
            elif child.tag == "Material":
                if material is not None:
                    raise self.fail(child, "a file holds one <Material>; found a second one")
                material = self.material(child)
            elif child.tag == "Fitting":
                fittings.append(self.fitting(child))
            else:
                self.unknown(child, "BRDF")
                extra.append(copy.deepcopy(child))
        if material is None:
            raise self.fail(root, "no <Material>")
        return BRDFDocument(material, fittings, info, extra, self.path, self.summarised_warnings(),
                            list(dict.fromkeys(self.model_warnings)))

    def fitting(self, el: etree._Element) -> Fitting:
        known = {"error", "readOnly", "optimizerName"}
        error = el.get("error")
        read_only = el.get("readOnly", "0").strip().lower() in {"1", "true", "yes"}
        material = None
        statistics: dict = {}
        extra = []
        for child in el:
            if not isinstance(child.tag, str):
                continue
            if child.tag == "Material":
                if material is not None:  # as at top level: the two may disagree, and the last would win
                    raise self.fail(child, "a <Fitting> holds one <Material>; found a second one")
                material = self.material(child)
                if not isinstance(material, AnalyticMaterial):
                    raise self.fail(child, "a <Fitting> must hold an analytic material")
            elif child.tag == "FitStatistics":
                statistics = {k: _parse_scalar(v) for k, v in self.attributes(child).items()}
            else:
                self.unknown(child, "Fitting")
                extra.append(copy.deepcopy(child))
        if material is None:
            raise self.fail(el, "a <Fitting> without a <Material>")
        return Fitting(
            material,
            None if error is None else self.number(el, "error", error),
            read_only,
            el.get("optimizerName", "LevenbergMarquardt"),
            statistics,
            {k: v for k, v in self.attributes(el).items() if k not in known},
            extra,
            el,
        )

    def material(self, el: etree._Element) -> AnalyticMaterial | MeasuredReference:
        name = self.text(el, "Name", required=False) or ""
        mtype = self.text(el, "Type")
        for tag in ("LobeCombination", "Parameters", "Checksum", "Simulation"):
            self.single(el, tag)
        known = {"Name", "Type"}
        if mtype in SIMULATED_TYPES:
            return self.simulated(el, mtype, name)
        if mtype != ANALYTIC:
            if not name:
                raise self.fail(el, f"a {mtype} material must name its data file in <Name>")
            known |= {"Checksum"}
            checksum = el.find("Checksum")
            sha = checksum.text.strip() if checksum is not None and checksum.text else None
            extra = self.leftovers(el, known, "Material")
            return MeasuredReference(mtype, name, self.base_dir, sha, extra, el)
        combination = self.text(el, "LobeCombination")
        if combination not in ("Linear", "Fixed"):
            raise self.fail(el.find("LobeCombination"), "LobeCombination must be Linear or Fixed")
        params = el.find("Parameters")
        if params is None:
            raise self.fail(el, "an analytic material needs <Parameters nChannels=.. nLobes=..>")
        n_channels = self.integer(params, "nChannels")
        n_lobes = self.integer(params, "nLobes")
        if not 1 <= n_channels <= MAX_CHANNELS:
            raise self.fail(params, f"nChannels={n_channels} (must be 1..{MAX_CHANNELS})")
        if not 0 <= n_lobes <= MAX_LOBES:
            raise self.fail(params, f"nLobes={n_lobes} (must be 0..{MAX_LOBES})")
        declared = sum(1 for child in params if child.tag == "Lobe")
        if declared != n_lobes:  # counted before any lobe is built
            raise self.fail(params, f"nLobes={n_lobes} but {declared} <Lobe> elements")
        lobes = self.lobes(params, combination, n_channels)
        extra = self.leftovers(el, known | {"LobeCombination", "Parameters"}, "Material")
        mat = AnalyticMaterial(name or "material", combination, n_channels, lobes, extra, el)
        try:
            mat.validate()
        except BRDFLabError as e:
            raise self.fail(params, str(e)) from None
        empty = mat.channels_without_lobes() if lobes else []
        if empty:
            raise self.fail(params, f"a Fixed material needs a lobe for every channel; no lobe for channel "
                                    f"{', '.join(map(str, empty))} (it would be black)")
        return mat

    def simulated(self, el: etree._Element, mtype: str, name: str) -> SimulatedReference:
        sim = el.find("Simulation")
        if sim is None or not sim.get("model"):
            raise self.fail(el, f"a {mtype} material needs <Simulation model=..>")
        p_el = sim.find("Parameters")
        params = {} if p_el is None else self.attributes(p_el)
        settings = {k: v for k, v in self.attributes(sim).items() if k != "model"}
        extra = self.leftovers(el, {"Name", "Type", "Simulation"}, "Material")
        return SimulatedReference(mtype, name or sim.get("model"), sim.get("model"), params, settings, extra, el)

    def leftovers(self, el: etree._Element, known: set[str], parent: str) -> list:
        out = []
        for child in el:
            if isinstance(child.tag, str) and child.tag not in known:
                self.unknown(child, parent)
                out.append(copy.deepcopy(child))
        return out

    def lobes(self, params: etree._Element, combination: str, n_channels: int) -> list[Lobe]:
        lobes: list[Lobe] = []
        pending_scale: list[float] | None = None
        pending_el = None
        leading = []  # unknown elements before the first lobe: written before it
        for child in params:
            if not isinstance(child.tag, str):
                continue
            if child.tag == "ScalingFactors":
                if combination == "Fixed":
                    raise self.fail(child, "a Fixed material has no scaling factors")
                if pending_scale is not None:
                    raise self.fail(child, "two <ScalingFactors> in a row")
                pending_scale = self.scaling_factors(child, n_channels)
                pending_el = child
            elif child.tag == "Lobe":
                if combination == "Linear":
                    if pending_scale is None:
                        raise self.fail(child, "in a Linear material each <Lobe> follows its <ScalingFactors>")
                    lobes.append(self.lobe(child, combination, pending_scale, pending_el))
                    pending_scale = pending_el = None
                else:
                    lobes.append(self.lobe(child, combination, None, None))
            else:
                self.unknown(child, "Parameters")
                if lobes:
                    lobes[-1].extra.append(("Parameters", copy.deepcopy(child)))
                else:
                    leading.append(("Before", copy.deepcopy(child)))
        if pending_scale is not None:
            raise self.fail(params, "<ScalingFactors> without a following <Lobe>")
        if lobes:
            lobes[0].extra[:0] = leading
        return lobes

    def scaling_factors(self, el: etree._Element, n_channels: int) -> list[float]:
        names = [f"channel{c}" for c in range(n_channels)]
        attrs = self.attributes(el)
        extra = sorted(set(attrs) - set(names))
        if extra:
            raise self.fail(el, f"unexpected attribute(s) {', '.join(extra)} for {n_channels} channels")
        missing = [n for n in names if n not in attrs]
        if missing:
            raise self.fail(el, f"missing {', '.join(missing)} ({n_channels} channels)")
        return [self.number(el, n, attrs[n]) for n in names]

    def lobe(self, el: etree._Element, combination: str, scale: list[float] | None,
             scale_el: etree._Element | None) -> Lobe:
        model_name = self.text(el, "Model")
        self.text(el, "Type", required=False)
        self.single(el, "ModelFile")
        model = self.model_of(el, model_name)
        p_el = self.single(el, "Parameters")
        given = {} if p_el is None else {k: self.number(p_el, k, v) for k, v in self.attributes(p_el).items()}
        channel = None
        if combination == "Fixed":
            channel = self.integer(el, "channel")
            value = given.pop("value", None)
            if value is None:
                if model.name == "Lambertian":
                    raise self.fail(p_el if p_el is not None else el, "a Fixed Lambertian lobe needs value=..")
                value = 1.0
            scale = [value]
        params = model.complete(given)
        lobe = Lobe(model, params, list(scale), channel, source=(scale_el, el))
        try:
            lobe.validate()
        except BRDFLabError as e:
            raise self.fail(p_el if p_el is not None else el, str(e)) from None
        for child in el:
            if isinstance(child.tag, str) and child.tag not in {"Model", "Type", "Parameters", "ModelFile"}:
                self.unknown(child, "Lobe")
                lobe.extra.append(("Lobe", copy.deepcopy(child)))
        return lobe


    def model_of(self, el: etree._Element, model_name: str):
        """The lobe's model: a <ModelFile> names the file model's file (relative to the
        material) and checksum; else a built-in, else a model read from the model folders."""
        from brdflab.models.files.library import MissingModelFile, resolve_reference
        from brdflab.models.registry import find_file_model

        ref = el.find("ModelFile")
        try:
            if ref is not None:
                model = resolve_reference(model_name, ref.get("path"), ref.get("sha256"), self.base_dir)
                if ref.get("sha256") and ref.get("sha256") != model.origin.sha256:
                    self.model_warnings.append(f"line {ref.sourceline}: the model file {model.origin.path} is not "
                                               "the one the material was saved with (its sha256 differs)")
                    self.warnings.append(self.model_warnings[-1])
                return model
            try:
                return get_model(model_name)
            except BRDFLabError:
                found = find_file_model(model_name)
                if found is None:
                    raise
                return found
        except MissingModelFile as e:
            where = self.fail(el.find("Model") if ref is None else ref, str(e))
            raise MissingModelFile(str(where), None, e.model_name, e.recorded) from None
        except BRDFLabError as e:
            raise self.fail(el.find("Model") if ref is None else ref, str(e)) from None


def element_text(el: etree._Element | None) -> str | None:
    """An element's text, stripped, without the comments and processing instructions inside it
    (`<Model><!-- note -->Ward</Model>` says Ward); None when there is none."""
    if el is None:
        return None
    text = "".join(el.xpath("text()")).strip()
    return text or None


def model_file_element(model, base_dir: Path | None) -> etree._Element:
    """<ModelFile path=".." sha256=".."/>: where a file model came from, relative to the
    material's folder where it can be, so that the pair moves together."""
    target = model.origin.path
    path = str(target)
    if base_dir is not None:
        try:
            path = os.path.relpath(target, Path(base_dir).resolve())
        except ValueError:  # another drive
            pass
    return etree.Element("ModelFile", {"path": Path(path).as_posix(), "sha256": model.origin.sha256})


_WRITE_DIR: list[Path | None] = [None]  # the folder a document is being written to (save)


def _parse_scalar(text: str):
    """An int or a finite float, else the text as it is (Infinity and NaN are not JSON)."""
    for conv in (ascii_integer, ascii_number):
        try:
            value = conv(text)
        except ValueError:
            continue
        if math.isfinite(value):
            return value
    return text


def parse_bytes(data: bytes, path: Path | str | None = None, base_dir: Path | None = None) -> BRDFDocument:
    """Parse a document from bytes; BRDFLabError (naming `path`) on any problem."""
    reader = _Reader(None if path is None else Path(path), base_dir)
    root, doctype = checked_root(data, path)
    doc = reader.document(root)
    doc.doctype = doctype
    doc.source = SourceXML(data, root)
    return doc


def checked_root(data: bytes, path, kind: str = "material") -> tuple[etree._Element, str | None]:
    """The root of an XML file of the lab's (a material, a model descriptor) parsed with
    entities, DTDs and the network off, and the name of its bare DOCTYPE line; BRDFLabError
    (naming `path`) for malformed XML, an empty document, a DOCTYPE that is more than a
    name, any entity, or more than MAX_ELEMENTS elements."""
    try:
        root = etree.fromstring(data, etree.XMLParser(**_PARSER_OPTIONS))
    except etree.XMLSyntaxError as e:
        raise BRDFLabError(syntax_problem(e), path) from None
    if root is None:
        raise BRDFLabError("empty XML document", path)
    doctype = _checked_doctype(root, data, path, kind)
    elements = int(root.xpath("count(//*)"))
    if elements > MAX_ELEMENTS:
        raise BRDFLabError(f"{elements:,} elements is more than the {MAX_ELEMENTS:,} a {kind} file may hold", path)
    if any(isinstance(node, etree._Entity) for node in root.iter()):
        raise BRDFLabError(f"entity references are not accepted in {kind} files", path)
    return root, doctype


_LIBXML2_ERRORS = {code: name for name, code in vars(etree.ErrorTypes).items() if name.startswith("ERR_")}
_PHRASES = {"ERR_RESOURCE_LIMIT": "beyond a parser limit (elements nested deeper than 256, or a text or name too long)"}


def syntax_problem(e: etree.XMLSyntaxError) -> str:
    """What is wrong with malformed XML, where, without libxml2's own words: they quote the
    file (tag names, entity names, the encoding it declares), and a refused file's bytes
    never reach a message."""
    name = _LIBXML2_ERRORS.get(e.code, "ERR_UNKNOWN")
    line, column = e.position if e.position else (0, 0)
    problem = _PHRASES.get(name, name.removeprefix("ERR_").lower().replace("_", " "))
    return f"malformed XML at line {line}, column {column}: {problem} (libxml2 error {e.code})"


_BARE_DOCTYPE = re.compile(r"<!DOCTYPE\s+([A-Za-z_][\w.-]*)\s*>", re.ASCII)


def _checked_doctype(root: etree._Element, data: bytes, path, kind: str = "material") -> str | None:
    """The name of a bare `<!DOCTYPE NAME>` line (as BRDFLab's Qt writer puts there), or None.

    Judged on the parsed document, so that every encoding is judged alike: lxml's DTD of the
    file (parsed with entities and DTD loading off) must declare no entity (general or
    parameter: lxml substitutes internal entities in attribute values even so) and name no
    SYSTEM/PUBLIC identifier; the DOCTYPE's text, decoded as the parser decoded it, must be
    bare (an internal subset could hold declarations lxml does not list).
    """
    info = root.getroottree().docinfo
    dtd = info.internalDTD
    if dtd is None:
        return None
    if next(iter(dtd.iterentities()), None) is not None:
        raise BRDFLabError(f"entity declarations are not accepted in {kind} files", path)
    if info.public_id or info.system_url or next(iter(dtd.iterelements()), None) is not None:
        raise _not_bare(path, kind)
    bom, codec = codec_of(data, info.encoding or "UTF-8")
    try:
        text = data[len(bom):].decode(codec, errors="replace")
    except LookupError:  # an encoding libxml2 knows and Python does not: nothing to check it with
        raise _not_bare(path, kind) from None
    start = text.find("<!DOCTYPE")
    match = _BARE_DOCTYPE.match(text, start)
    if start < 0 or match is None or text.find("<!DOCTYPE", match.end()) >= 0:
        raise _not_bare(path, kind)
    return match.group(1)


def _not_bare(path, kind: str) -> BRDFLabError:
    return BRDFLabError(f"only a bare DOCTYPE line (e.g. <!DOCTYPE BRDF>) is accepted in {kind} files; "
                        "internal subsets and SYSTEM/PUBLIC identifiers are refused", path)


def load(path: str | os.PathLike) -> BRDFDocument:
    """Read an XML material file."""
    path = Path(path)
    return parse_bytes(read_bounded(path, MAX_XML_BYTES, "a material file"), path, path.parent)


# --------------------------------------------------------------------------------------
# writing

def _num(v: float) -> str:
    return repr(float(v))


def lobe_type(lobe: Lobe) -> str:
    """What <Type> says of a lobe: Isotropic unless its parameters make it anisotropic."""
    return "Isotropic" if lobe.model.is_isotropic(lobe.params) else "Anisotropic"


def lobe_elements(lobe: Lobe, combination: str) -> list[etree._Element]:
    """A new lobe's elements: its <ScalingFactors> (Linear) and its <Lobe>, with the unknown
    elements read before and after them."""
    out = [copy.deepcopy(x) for where, x in lobe.extra if where == "Before"]
    if combination == "Linear":
        out.append(etree.Element("ScalingFactors", {f"channel{c}": _num(s) for c, s in enumerate(lobe.scale)}))
    lobe_el = etree.Element("Lobe")
    if combination == "Fixed":
        lobe_el.set("channel", str(lobe.channel))
    etree.SubElement(lobe_el, "Model").text = lobe.model.xml_name
    etree.SubElement(lobe_el, "Type").text = lobe_type(lobe)
    attrs = {k: _num(lobe.params[k]) for k in lobe.model.parameter_names}
    if combination == "Fixed":
        attrs["value"] = _num(lobe.scale[0])
    etree.SubElement(lobe_el, "Parameters", attrs)
    if lobe.model.origin is not None:
        lobe_el.append(model_file_element(lobe.model, _WRITE_DIR[0]))
    lobe_el.extend(copy.deepcopy(x) for where, x in lobe.extra if where == "Lobe")
    out.append(lobe_el)
    out.extend(copy.deepcopy(x) for where, x in lobe.extra if where == "Parameters")
    return out


def material_element(material: AnalyticMaterial | MeasuredReference | SimulatedReference) -> etree._Element:
    """A new <Material> element holding `material`."""
    el = etree.Element("Material")
    etree.SubElement(el, "Name").text = material.name
    if isinstance(material, SimulatedReference):
        etree.SubElement(el, "Type").text = material.type
        sim = etree.SubElement(el, "Simulation", {"model": material.model, **material.settings})
        etree.SubElement(sim, "Parameters", material.parameters)
        el.extend(copy.deepcopy(x) for x in material.extra)
        return el
    if isinstance(material, MeasuredReference):
        etree.SubElement(el, "Type").text = material.type
        if material.sha256:
            c = etree.SubElement(el, "Checksum", algorithm="sha256")
            c.text = material.sha256
        el.extend(copy.deepcopy(x) for x in material.extra)
        return el
    etree.SubElement(el, "Type").text = ANALYTIC
    etree.SubElement(el, "LobeCombination").text = material.combination
    params = etree.SubElement(
        el, "Parameters", nChannels=str(material.n_channels), nLobes=str(len(material.lobes))
    )
    for lobe in material.lobes:
        params.extend(lobe_elements(lobe, material.combination))
    el.extend(copy.deepcopy(x) for x in material.extra)
    return el


def fitting_attributes(fit: Fitting) -> dict[str, str]:
    attrs = {}
    if fit.error is not None:
        attrs["error"] = _num(fit.error)
    attrs["readOnly"] = "1" if fit.read_only else "0"
    attrs["optimizerName"] = fit.optimizer
    attrs.update(fit.attributes)
    return attrs


def fitting_element(fit: Fitting) -> etree._Element:
    """A new <Fitting> element holding `fit`."""
    f_el = etree.Element("Fitting", fitting_attributes(fit))
    f_el.append(material_element(fit.material))
    if fit.statistics:
        etree.SubElement(f_el, "FitStatistics", {k: str(v) for k, v in fit.statistics.items()})
    f_el.extend(copy.deepcopy(x) for x in fit.extra)
    return f_el


def document_element(doc: BRDFDocument) -> etree._Element:
    """A new <BRDF> element holding `doc` (for documents not read from a file)."""
    root = etree.Element("BRDF")
    if doc.info is not None:
        root.append(copy.deepcopy(doc.info))
    else:
        info = etree.SubElement(root, "Info")
        etree.SubElement(info, "Program").text = "brdflab"
    root.append(material_element(doc.material))
    root.extend(fitting_element(fit) for fit in doc.fittings)
    root.extend(copy.deepcopy(x) for x in doc.extra)
    return root


def to_bytes(doc: BRDFDocument) -> bytes:
    """The file text of `doc`: for a document read from a file, that file with the current
    values written into it (byte for byte the same where nothing changed)."""
    if doc.source is not None:
        from brdflab.io.xml_update import updated_draft

        return updated_draft(doc).to_bytes()
    doctype = f"<!DOCTYPE {doc.doctype}>" if doc.doctype else None
    return etree.tostring(
        document_element(doc), pretty_print=True, xml_declaration=True, encoding="UTF-8", doctype=doctype)


def to_text(doc: BRDFDocument) -> str:
    """The file text of `doc` as a string (decoded from the encoding it is written in)."""
    return doc.source.decode(to_bytes(doc)) if doc.source is not None else to_bytes(doc).decode("UTF-8")


def save(doc: BRDFDocument, path: str | os.PathLike) -> None:
    """Write `doc` to `path` atomically. Measured data paths stay relative to the file."""
    path = Path(path)
    atomic_write(path, serialized(doc, path))
    doc.path = path


def serialized(doc: BRDFDocument, path: Path) -> bytes:
    """The bytes `save` writes for `doc` at `path` (data and model files named relative to
    it); BRDFLabError, naming `path`, when a file name it must record is not XML text: a name
    that is not UTF-8 reaches Python as lone surrogates (PEP 383), which lxml refused with a
    UnicodeEncodeError traceback."""
    if isinstance(doc.material, MeasuredReference):
        doc.material = _rebase(doc.material, path.parent)
    _WRITE_DIR[0] = path.parent
    try:
        return to_bytes(doc)
    except ValueError:  # UnicodeEncodeError (not UTF-8), or lxml's refusal of a control character
        raise BRDFLabError("cannot save: a data or model file it names has a name that is not UTF-8 text, "
                           "which an XML material cannot hold (rename that file)", path) from None
    finally:
        _WRITE_DIR[0] = None


def check_savable(doc: BRDFDocument, path: str | os.PathLike, fit: AnalyticMaterial | None = None) -> None:
    """The BRDFLabError `save` would raise for `doc` with `fit` stored in it, raised before
    the work (a fit) whose result would then be lost; writes nothing."""
    probe = copy.copy(doc)
    probe.fittings = [*doc.fittings, *([Fitting(fit)] if fit is not None else [])]
    serialized(probe, Path(path))


def _rebase(ref: MeasuredReference, new_dir: Path) -> MeasuredReference:
    """The same data file, named relative to a new XML location when possible."""
    target = ref.path
    if Path(ref.name).is_absolute():
        return ref
    try:
        rel = os.path.relpath(target.resolve(), new_dir.resolve())
    except ValueError:
        rel = str(target.resolve())
    return MeasuredReference(ref.type, Path(rel).as_posix(), new_dir, ref.sha256, ref.extra, ref.source)
