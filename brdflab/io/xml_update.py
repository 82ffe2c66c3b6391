"""Saving a document that was read from a file: its current values go into a draft of
the tree it was read from (brdflab.io.xml_source).

Every element a value came from is found again through the value's `source` and only
the values that changed are rewritten: a number equal to the file's keeps the file's
spelling, Ward's lone `ax` stays alone while ay = ax, a lobe's <Type> changes only when
an edit makes it untrue. Comments, processing instructions, unknown elements and
attributes, a second <Info> and the layout stay where they were. Lobes or fits that were
added, removed or moved are inserted and removed with the file's own indentation.
"""

from __future__ import annotations

import copy

from lxml import etree

from brdflab.io import xmlio
from brdflab.io.xml_source import Draft
from brdflab.material.analytic import AnalyticMaterial, Lobe

Group = list  # the elements one object is written as (a lobe: its <ScalingFactors> and <Lobe>)


def updated_draft(doc: "xmlio.BRDFDocument") -> Draft:
    """A draft of `doc`'s source tree holding `doc`'s current values."""
    draft = doc.source.draft(doc.doctype)
    _Updater(draft).document(doc)
    return draft


def _same_number(text: str | None, value: float) -> bool:
    try:
        return text is not None and repr(float(text)) == repr(float(value))
    except ValueError:
        return False


def _set_number(el: etree._Element, name: str, value: float) -> bool:
    """Write `value` unless the attribute already holds that number; whether it changed."""
    if _same_number(el.get(name), value):
        return False
    el.set(name, xmlio._num(value))
    return True


def _set_integer(el: etree._Element, name: str, value: int) -> None:
    old = el.get(name)
    try:
        if old is not None and int(old) == value:
            return
    except ValueError:
        pass
    el.set(name, str(value))


def _set_attributes(el: etree._Element, wanted: dict[str, str]) -> None:
    """Make el's attributes `wanted`, those it had staying in the file's order."""
    for name in list(el.attrib):
        if name not in wanted:
            del el.attrib[name]
    for name, value in wanted.items():
        if el.get(name) != value:
            el.set(name, value)


class _Updater:
    def __init__(self, draft: Draft) -> None:
        self.draft = draft
        self.claimed: set = set()
        text = draft.root.text
        # the file's indentation step, or None for a file written without line breaks
        self.unit = text.rsplit("\n", 1)[1] if text and "\n" in text and not text.strip() else None

    # --- finding and placing elements -------------------------------------------------
    def own(self, source: etree._Element | None, parent: etree._Element) -> etree._Element | None:
        """The draft's element for `source` when it sits in `parent` and is not used yet, a
        copy of it when it comes from elsewhere (another file, another fit), else None."""
        if source is None:
            return None
        el = self.draft.own(source)
        if el is not None and el.getparent() is parent and el not in self.claimed:
            self.claimed.add(el)
            return el
        out = copy.deepcopy(source)
        out.tail = None
        return out

    def indent(self, el: etree._Element, depth: int) -> None:
        if self.unit is not None and not self.draft.is_original(el):
            etree.indent(el, space=self.unit, level=depth)

    def line_start(self, depth: int) -> str | None:
        return None if self.unit is None else "\n" + self.unit * depth

    @staticmethod
    def depth(el: etree._Element) -> int:
        return sum(1 for _ in el.iterancestors())

    def insert_after(self, parent: etree._Element, prev, el: etree._Element) -> None:
        """Put `el` after `prev` (first when None), indented as its new siblings are."""
        depth = self.depth(parent) + 1
        self.indent(el, depth)
        before = parent.text if prev is None else prev.tail
        if prev is None:
            parent.insert(0, el)
        else:
            prev.addnext(el)
        el.tail = before
        start = self.line_start(depth)
        if start is not None:
            if prev is None:
                parent.text = start
            else:
                prev.tail = start

    @staticmethod
    def remove(el: etree._Element) -> None:
        """Take `el` out; when it was last, what closed the parent closes it still."""
        parent, prev = el.getparent(), el.getprevious()
        if el.getnext() is None:
            if prev is None:
                parent.text = el.tail
            else:
                prev.tail = el.tail
        parent.remove(el)

    def replace(self, old: etree._Element | None, new: etree._Element, parent: etree._Element, prev=None) -> None:
        if new is old:
            return
        if old is None:
            self.insert_after(parent, prev, new)
            return
        self.indent(new, self.depth(parent) + 1)
        tail = old.tail
        parent.replace(old, new)
        new.tail = tail

    def reconcile(self, parent: etree._Element, original: list[Group], current: list[Group], anchor) -> None:
        """Make `parent` hold the groups `current` where it held `original`: kept groups stay
        in place, removed ones go, new ones come after their predecessor."""
        old = [e for g in original for e in g]
        new = [e for g in current for e in g]
        if old:
            anchor = old[0].getprevious()
            while anchor is not None and anchor in old:
                anchor = anchor.getprevious()
        kept = {e for e in new if e.getparent() is parent}
        for e in old:
            if e not in kept:
                self.remove(e)
        in_place = [e for e in parent if e in kept]
        if in_place != [e for e in new if e in kept]:  # moved: every group is placed again
            for e in in_place:
                self.remove(e)
        prev = anchor
        for e in new:
            if e.getparent() is not parent:
                self.insert_after(parent, prev, e)
            prev = e

    # --- the document ---------------------------------------------------------------------
    def document(self, doc) -> None:
        root = self.draft.root
        old_material = root.find("Material")
        material = self.material(self.own(doc.material.source, root), doc.material)
        self.replace(old_material, material, root)
        original = [[el] for el in root if el.tag == "Fitting"]
        current = [[self.fitting(self.own(fit.source, root), fit)] for fit in doc.fittings]
        self.reconcile(root, original, current, material)

    def fitting(self, el: etree._Element | None, fit) -> etree._Element:
        if el is None:
            return xmlio.fitting_element(fit)
        if fit.error is None:
            el.attrib.pop("error", None)
        else:
            _set_number(el, "error", fit.error)
        if (el.get("readOnly", "0").strip().lower() in {"1", "true", "yes"}) != fit.read_only:
            el.set("readOnly", "1" if fit.read_only else "0")
        if el.get("optimizerName", "LevenbergMarquardt") != fit.optimizer:
            el.set("optimizerName", fit.optimizer)
        known = {"error", "readOnly", "optimizerName"}
        for name in [k for k in el.attrib if k not in known and k not in fit.attributes]:
            del el.attrib[name]
        for name, value in fit.attributes.items():
            if el.get(name) != value:
                el.set(name, value)
        old_material = el.find("Material")
        material = self.material(self.own(fit.material.source, el), fit.material)
        self.replace(old_material, material, el)
        self.statistics(el, material, fit.statistics)
        return el

    def statistics(self, fitting: etree._Element, material: etree._Element, stats: dict) -> None:
        el = fitting.find("FitStatistics")
        if not stats:
            if el is not None:
                self.remove(el)
            return
        if el is None:
            el = etree.Element("FitStatistics")
            self.insert_after(fitting, material, el)
        for name in [k for k in el.attrib if k not in stats]:
            del el.attrib[name]
        for name, value in stats.items():
            old = el.get(name)
            if old is None or xmlio._parse_scalar(old) != value or type(xmlio._parse_scalar(old)) is not type(value):
                el.set(name, str(value))

    # --- materials --------------------------------------------------------------------------
    def material(self, el: etree._Element | None, material) -> etree._Element:
        kind = None if el is None else self.kind_of(el)
        if kind != type(material):
            return xmlio.material_element(material)
        if isinstance(material, AnalyticMaterial):
            self.child_text(el, "Name", material.name, implied="material")
            self.analytic(el, material)
        elif isinstance(material, xmlio.SimulatedReference):
            self.child_text(el, "Name", material.name, implied=material.model)
            self.child_text(el, "Type", material.type)
            self.simulation(el, material)
        else:
            self.child_text(el, "Name", material.name)
            self.child_text(el, "Type", material.type)
            self.checksum(el, material.sha256)
        return el

    @staticmethod
    def kind_of(el: etree._Element) -> type:
        text = xmlio.element_text(el.find("Type"))
        if text == xmlio.ANALYTIC:
            return AnalyticMaterial
        return xmlio.SimulatedReference if text in xmlio.SIMULATED_TYPES else xmlio.MeasuredReference

    def child_text(self, el: etree._Element, tag: str, value: str, implied: str | None = None) -> None:
        """Set the text of el's first <tag> to `value` unless it already says so (or, for an
        absent or empty element, unless `value` is what the reader makes of that)."""
        child = el.find(tag)
        text = xmlio.element_text(child)
        if text == value or (text is None and value in (implied, "")):
            return
        if child is None:
            child = etree.Element(tag)
            self.insert_after(el, None, child)
        child.text = value
        for node in child:  # comments inside keep their place; the text after them goes
            node.tail = None

    def checksum(self, el: etree._Element, sha256: str | None) -> None:
        child = el.find("Checksum")
        if sha256 is None:
            if child is not None:
                self.remove(child)
            return
        if child is None:
            child = etree.Element("Checksum", algorithm="sha256")
            self.insert_after(el, el.find("Type"), child)
        if (child.text or "").strip() != sha256:
            child.text = sha256

    def simulation(self, el: etree._Element, material) -> None:
        sim = el.find("Simulation")
        if sim is None:
            sim = etree.Element("Simulation")
            self.insert_after(el, el.find("Type"), sim)
        _set_attributes(sim, {"model": material.model, **material.settings})
        params = sim.find("Parameters")
        if params is None:
            params = etree.Element("Parameters")
            self.insert_after(sim, None, params)
        _set_attributes(params, dict(material.parameters))

    def analytic(self, el: etree._Element, material: AnalyticMaterial) -> None:
        self.child_text(el, "LobeCombination", material.combination)
        params = el.find("Parameters")
        _set_integer(params, "nChannels", material.n_channels)
        _set_integer(params, "nLobes", len(material.lobes))
        current = [self.lobe(params, lobe, material.combination) for lobe in material.lobes]
        self.reconcile(params, _lobe_groups(params), current, None)

    # --- lobes ------------------------------------------------------------------------------
    def lobe(self, params: etree._Element, lobe: Lobe, combination: str) -> Group:
        scale_source, lobe_source = lobe.source if lobe.source is not None else (None, None)
        lobe_el = self.own(lobe_source, params)
        if lobe_el is None:
            return xmlio.lobe_elements(lobe, combination)
        group = [lobe_el]
        if combination == "Linear":
            scale_el = self.own(scale_source, params) if scale_source is not None else None
            if scale_el is None:
                scale_el = etree.Element("ScalingFactors")
            names = {f"channel{c}" for c in range(len(lobe.scale))}
            for name in [k for k in scale_el.attrib if k not in names]:
                del scale_el.attrib[name]
            for c, s in enumerate(lobe.scale):
                _set_number(scale_el, f"channel{c}", s)
            group.insert(0, scale_el)
        else:
            _set_integer(lobe_el, "channel", lobe.channel)
        model = lobe_el.find("Model")
        model_changed = xmlio.element_text(model) != lobe.model.xml_name
        self.child_text(lobe_el, "Model", lobe.model.xml_name)
        self.model_file(lobe_el, lobe.model)
        p_el = lobe_el.find("Parameters")
        if p_el is None:  # a file may leave out an empty <Parameters/>: added only when needed
            p_el = etree.Element("Parameters")
            changed = self.lobe_parameters(p_el, lobe, combination) or model_changed
            if len(p_el.attrib):
                anchor = lobe_el.find("Type")
                self.insert_after(lobe_el, anchor if anchor is not None else lobe_el.find("Model"), p_el)
        else:
            changed = self.lobe_parameters(p_el, lobe, combination) or model_changed
        declared = lobe_el.find("Type")
        says = xmlio.element_text(declared)
        if changed and (model_changed or (says == "Isotropic" and xmlio.lobe_type(lobe) != says)):
            self.child_text(lobe_el, "Type", xmlio.lobe_type(lobe))
        return group

    def model_file(self, lobe_el: etree._Element, model) -> None:
        """The lobe's <ModelFile> says where its file model is (none for a built-in)."""
        old = lobe_el.find("ModelFile")
        if model.origin is None:
            if old is not None:
                self.remove(old)
            return
        new = xmlio.model_file_element(model, xmlio._WRITE_DIR[0])
        if old is not None and dict(old.attrib) == dict(new.attrib):
            return
        if old is not None:
            self.remove(old)
        anchor = lobe_el.find("Parameters")
        self.insert_after(lobe_el, anchor if anchor is not None else lobe_el.find("Model"), new)

    def lobe_parameters(self, p_el: etree._Element, lobe: Lobe, combination: str) -> bool:
        """Write the lobe's parameters into its <Parameters>; whether any value changed.

        The file's own set of attributes is kept while it still says the same (Ward's lone
        `ax` while ay = ax, Ashikhmin–Shirley's `Exponent` while nu = nv = Exponent)."""
        names = lobe.model.parameter_names
        wanted = {k: float(lobe.params[k]) for k in names}
        trial = {}
        try:
            for k, text in p_el.attrib.items():
                if not (combination == "Fixed" and k == "value"):
                    trial[k] = wanted[k] if k in names else float(text)
            completed = lobe.model.complete(trial)
        except ValueError:
            completed = None
        changed = False
        if completed != wanted:
            for k in [k for k in p_el.attrib if k not in names and k != "value"]:
                del p_el.attrib[k]
                changed = True
            trial = wanted
        for k in names:
            if k in trial:
                changed |= _set_number(p_el, k, wanted[k])
        if combination == "Fixed":
            implied = p_el.get("value") is None and lobe.model.name != "Lambertian" and lobe.scale[0] == 1.0
            if not implied:
                changed |= _set_number(p_el, "value", lobe.scale[0])
        return changed


def _lobe_groups(params: etree._Element) -> list[Group]:
    """The lobes of a <Parameters> element as the file has them: [<ScalingFactors>, <Lobe>]
    in Linear materials, [<Lobe>] in Fixed ones."""
    groups: list[Group] = []
    scale = None
    for child in params:
        if child.tag == "ScalingFactors":
            scale = child
        elif child.tag == "Lobe":
            groups.append([child] if scale is None else [scale, child])
            scale = None
    return groups
