"""Import of DDA for Windows (ntdda) input files: ``read_ntdda(geometry, analysis)``.

ntdda is David Doolin's Windows/C port of Gen-Hua Shi's DDA (public source:
github.com/doolin/ntdda). A problem is two files: a *geometry* file (joint lines and
points; Shi's "DC" program cuts the lines into blocks) and an *analysis* file
(time stepping, block materials, joint properties, load histories, bolt properties).
Each comes in two encodings, told apart by the first token of the file, as
``ddafile_get_type`` (src/ddafile.c) does: ``<?`` is DDAML (XML), ``#!0xDDA-v1.5`` an
"extended" text format (its reader is not in the public sources; refused here), anything
else Shi's original plain-text format. What follows is what the readers in doolin/ntdda
do; every rule below names the function it was read from.

Geometry, DDAML (src/geomddaml.c, ``ddaml_read_geometry_file`` / ``parseGeometry``):
root element ``DDA`` (any namespace prefix), its child ``Geometry``, whose children are
matched by local name:

* ``Edgenodedist distance="e00"``: Shi's minimum edge-node distance (a fraction of the
  domain scale); used by ntdda to merge nearly-touching lines, not here (see below).
* ``Jointlist`` of ``Joint type="k"`` with text ``x1 y1 x2 y2``: the joint lines; ``k`` is
  the joint type, an index into the analysis file's joint properties.
* ``Fixedpointlist`` of ``Point`` (``x y``) and ``Line`` (``x1 y1 x2 y2``).
* ``Loadpointlist``, ``Measuredpointlist``, ``Holepointlist`` of ``Point`` (``x y``).
* ``Boltlist`` of ``Bolt`` (``x1 y1 x2 y2``: the two ends).
* ``Matlinelist`` of ``Line type="m"`` (``x1 y1 x2 y2``): material lines, ``m`` the block
  material number.
* ``Seismicpointlist`` and ``Boundlist`` are refused (no equivalent here; ntdda's own
  ``parseBoundlist`` writes to a list it never creates).

Geometry, plain text (src/geomreader.c, ``geometryReader1``; whitespace-separated, read
with ``fscanf``): ``e00``; ``nJoints nBoundaryLines``; ``nMatLines``; ``nBolts``;
``nFPoints``; ``nLPoints``; ``nMPoints``; ``nHPoints``; then ``nJoints`` rows
``x1 y1 x2 y2 type``; ``nMatLines`` rows ``x1 y1 x2 y2 material``; ``nFPoints`` rows
``x1 y1 x2 y2`` (fixed lines, a point when both ends coincide); ``nLPoints``, ``nMPoints``,
``nHPoints`` rows ``x y``. The reader reads ``nBolts`` but no bolt rows ("Rock bolts are not
yet implemented"), so a plain file with bolts is refused here. ``nBoundaryLines`` (the first
joints) only changes how ntdda merges close nodes (``dc04``, src/blocks.c), not the blocks.

Analysis, DDAML (src/analysisddaml.c, ``ddaml_read_analysis_file`` / ``parseAnalysis``):
children of ``DDA/Analysis``, by local name:

* ``Analysistype type="dynamic"`` (anything else: static) -> ``settings.dynamic`` 1 / 0.
* ``Numtimesteps timesteps="n"`` -> ``settings.steps``;
  ``Maxtimestep maxtimestep="dt"`` -> ``settings.dt`` (ntdda may shorten steps below it).
* ``Planestrain flag="yes"`` -> every material ``"plane": "strain"``.
* ``Blockmaterial`` (one per block material number, numbered 1, 2, ... in order of
  appearance: ``transferBlockMatlistToAStruct`` ignores the ``type`` attribute) with
  children ``Unitmass``, ``Unitweight``, ``Youngsmod``, ``Poissonratio``, ``Damping``,
  ``Istress`` (sx sy txy), ``Istrain`` (3 values), ``Ivelocity`` (vx vy vr).
* ``Jointproperties`` (joint types 1, 2, ... in order of appearance, ``type`` ignored:
  ``transferJointMatlistToAStruct``) with ``Friction`` (an angle in degrees: the contact
  code uses ``tan(dd*phi)``, dd = pi/180, ``setFrictionForces`` in src/combineddf.c),
  ``Cohesion`` and ``Tensile`` (stresses: force = value x contact length, same function).
* ``Loadpointlist`` of ``Loadpoint numpoints="n"`` whose text is n records ``t fx fy;``
  separated by ``;`` (``parseLoadpoints``); the i-th ``Loadpoint`` belongs to the i-th load
  point of the geometry file. ntdda interpolates the force linearly in time between
  records (``df09``, called from ``assemble`` in src/loadmatrix.c).
* ``Boltproperties`` with text ``stiffness strength pretension``; every bolt takes the
  first one (``bolt_init_materials``, src/bolt.c). The bolt force is
  stiffness x (length - reference length) with reference length = initial length -
  pretension / stiffness (``bolt_set_ref_length_a``), tension positive; ``strength`` is
  never used.
* ``Gravity``, ``Autotimestep``, ``Autopenalty``, ``Rotation``, ``AConstants``,
  ``Opencloselimit``, ``Saveinterval``, ``Mintimestep``, ``Maxdisplacement``,
  ``ContactDamping``, ``Gravaccel``, ``Writevertices``: ntdda's solver controls (penalty,
  open-close, the "gravity turn-on" phase); nothing here corresponds, they are ignored.
  ``Timehistory`` (an earthquake record file) is refused.

Analysis, plain text (src/analysisreader.c, ``ddafile_read_original_analysis``):
``analysistype`` (1 dynamic, 0 static), ``nTimeSteps``, ``nBlockMats``, ``nJointMats``,
``maxdisplacement``, ``maxtimestep``; then per block material 13 numbers
``ma we e0 u0 s11 s22 s12 t11 t22 t12 vx vy vr`` (unit mass, unit weight, E, nu, initial
stress, initial strain, initial velocity, as the reader's comment names them); then per
joint type ``friction-angle cohesion tension``. The format carries no load histories
(ntdda applies zero force at plain-format load points) and no bolt properties.

Blocks (src/geomdriver.c ``ddacut``, src/blocks.c ``dc04``-``dc16``): the joint lines are
intersected, dangling pieces pruned ("tree cutting", ``dc05``/``dc06``), and the bounded
faces of what remains are the blocks (``dc08`` drops the outer face); every block vertex
carries the joint type of the line of its edge (``vertices[][0] = joints[j][5]``). Here
``cutting.cut_blocks`` does this with a box larger than every line and the faces touching
the box dropped. Then, as ntdda does: a block lying inside another block is dropped
(``dc16``); blocks containing a hole point are deleted (``dc11``); block materials
(``dc13``): every block with an edge crossed by a material line takes its number (later
lines win), a material line crossing no edge gives its number to the block holding its
first end, and blocks left without one get material 1. Fixed lines (``dc10``) become fixed
points: one per block edge the line crosses, at the crossing moved 0.005 w0 into that
block along the edge's inward normal (w0: the domain scale of ``computeDomainscale``,
src/geometrydata.c: half the larger of the height and width / 1.3 of the joints' bounding
box, times 1.02); a fixed line crossing no edge is a point at its first end. A fixed,
load, measured point or bolt end belongs to the block that contains it (``dc11``,
``dc14``).

Conversions (ntdda has no units; the numbers are taken as SI with unit thickness):

* density (kg/m^2 in 2D) = ``Unitmass`` (the mass ntdda's inertia uses). ntdda's body force
  is -``Unitweight`` x area, downwards (``df16``, src/loadmatrix.c), so gravity is
  (0, -Unitweight / Unitmass); it must be the same for every block material used (one
  gravity here), else a SceneError.
* friction = tan(angle in degrees).
* cohesion: ntdda gives each vertex-edge contact cohesion x half the overlap of the two
  edges (``proj``: ``c_length[i][3] = .5*(s[3]-s[2])...``), so an edge-edge interface
  gets cohesion x its length L in all; jaxdda's cohesion is that total, one force per
  interface. A joint type here has one value for all its interfaces, so the importer
  uses c x L_mean, L_mean the mean length of the joint type's interfaces at t = 0 (the
  stretches where two blocks' edges of that type meet; when it has none, the mean length
  of its block edges). Exact for interfaces of the mean length, proportionally off for
  the others.
* tensile: ntdda reads ``Tensile`` but never applies it (the line computing it is
  commented out in ``setFrictionForces``: "Tensile strength not used."), so by default the
  joints get tensile 0, as ntdda behaves; ``tensile=True`` converts it like cohesion
  (jaxdda then cements the blocks touching at t = 0, which ntdda does not).
* load histories: rows (t, fx, fy) as given; after the last record ntdda extrapolates
  the last segment, so when that segment has a slope and ends before steps x dt, a row
  at steps x dt continues it. (Before the first record ntdda also extrapolates the
  *last* segment; jaxdda holds the first value. A SceneError would be noisier than
  useful: histories start at t = 0 in practice.)
* bolts: a spring connector with ``stiffness`` and ``pretension`` from the first
  ``Boltproperties``.
* initial stress -> the body's ``stress``; initial velocity (vx, vy, vr) -> ``velocity``
  and ``angular_velocity``; both written only when not zero.

Not imported, with a warning when the file gives a non-zero value: block damping,
initial strain. Not reproduced: ntdda merges nodes closer than 1.25 e00 w0 and deletes
edges closer than e00 w0 to a node (``dc04``, ``dc06``) and merges collinear vertices of
different joints (``dc09``); here lines must meet to cut (to 1e-9 of the model size).
"""
from __future__ import annotations

import math
import warnings
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jaxdda.errors import SceneError
from jaxdda.scene import cutting


# -- reading -------------------------------------------------------------------------------
@dataclass
class _Item:
    values: tuple
    where: str  # "file, line N: <element>" for error messages
    kind: int = 0  # joint type, material number, ...


@dataclass
class _Geometry:
    path: str
    joints: list = field(default_factory=list)
    matlines: list = field(default_factory=list)
    fixed: list = field(default_factory=list)  # (x1, y1, x2, y2)
    loads: list = field(default_factory=list)
    measured: list = field(default_factory=list)
    holes: list = field(default_factory=list)
    bolts: list = field(default_factory=list)


@dataclass
class _Analysis:
    path: str
    dynamic: float = 1.0
    steps: int | None = None
    dt: float | None = None
    plane_strain: bool = False
    materials: list = field(default_factory=list)  # dicts, material number k at k - 1
    joints: list = field(default_factory=list)  # (phi, cohesion, tensile, where)
    loads: list = field(default_factory=list)  # _Item of rows, or None (plain format)
    bolt: tuple | None = None  # (stiffness, strength, pretension, where)
    plain: bool = False


def _file_type(path: Path) -> str:
    try:
        text = path.read_text(errors="replace")
    except OSError as err:
        raise SceneError(f"{path}: cannot be read ({err.strerror})") from None
    tokens = text.split()
    if not tokens:
        raise SceneError(f"{path}: the file is empty")
    if tokens[0].startswith("<?"):
        return "ddaml"
    if tokens[0].startswith("#!0xDDA-v1.5"):
        raise SceneError(f"{path}: the 'extended' (#!0xDDA-v1.5) format is not supported: its reader is not in the "
                         "public ntdda sources, so its layout cannot be established")
    return "plain"


class _Node:
    def __init__(self, name: str, attrs: dict, line: int):
        self.name, self.attrs, self.line = name, attrs, line
        self.children: list[_Node] = []
        self.parts: list[str] = []

    @property
    def text(self) -> str:  # xmlNodeListGetString(doc, cur->childs, 1): the element's own text
        return "".join(self.parts)


def _parse_xml(path: Path) -> _Node:
    parser = xml.parsers.expat.ParserCreate()
    root = _Node("", {}, 0)
    stack = [root]

    def start(name, attrs):
        node = _Node(name.split(":")[-1], attrs, parser.CurrentLineNumber)
        stack[-1].children.append(node)
        stack.append(node)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda name: stack.pop()
    parser.CharacterDataHandler = lambda data: stack[-1].parts.append(data)
    try:
        parser.Parse(path.read_bytes(), True)
    except xml.parsers.expat.ExpatError as err:
        reason = xml.parsers.expat.ErrorString(err.code)
        raise SceneError(f"{path}, line {err.lineno}: not well-formed XML ({reason})") from None
    if len(root.children) != 1 or root.children[0].name != "DDA":
        raise SceneError(f"{path}: the root element must be DDA (ntdda's ddaml_check_document)")
    return root.children[0]


def _where(path, node: _Node) -> str:
    return f"{path}, line {node.line}: <{node.name}>"


def _numbers(where: str, text: str, count: int | None, what: str) -> tuple:
    parts = text.split()
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise SceneError(f"{where}: {what} must be numbers, got {text.strip()!r}") from None
    if count is not None and len(values) != count:
        raise SceneError(f"{where}: {what} needs {count} numbers, got {len(values)} ({text.strip()!r})")
    if not all(math.isfinite(v) for v in values):
        raise SceneError(f"{where}: {what} must be finite, got {text.strip()!r}")
    return values


def _attr(where: str, node: _Node, name: str) -> str:
    if name not in node.attrs:
        raise SceneError(f"{where}: attribute '{name}' is missing")
    return node.attrs[name]


def _int_attr(where: str, node: _Node, name: str) -> int:
    value = _attr(where, node, name)
    try:
        return int(value.strip())
    except ValueError:
        raise SceneError(f"{where}: attribute '{name}' must be an integer, got {value!r}") from None


def _float_attr(where: str, node: _Node, name: str) -> float:
    value = _attr(where, node, name)
    try:
        out = float(value)
    except ValueError:
        raise SceneError(f"{where}: attribute '{name}' must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise SceneError(f"{where}: attribute '{name}' must be finite, got {value!r}")
    return out


def _section(path: Path, root: _Node, name: str) -> _Node:
    for child in root.children:
        if child.name == name:
            return child
    raise SceneError(f"{path}: no <{name}> element under <DDA>")


def _geometry_ddaml(path: Path) -> _Geometry:
    geo = _Geometry(str(path))
    section = _section(path, _parse_xml(path), "Geometry")
    points = {"Loadpointlist": geo.loads, "Measuredpointlist": geo.measured, "Holepointlist": geo.holes}
    for node in section.children:
        where = _where(path, node)
        if node.name == "Jointlist":
            for j in node.children:
                w = _where(path, j)
                if j.name != "Joint":
                    raise SceneError(f"{w}: expected <Joint> in <Jointlist>")
                geo.joints.append(_Item(_numbers(w, j.text, 4, "a joint (x1 y1 x2 y2)"), w, _int_attr(w, j, "type")))
        elif node.name == "Fixedpointlist":
            for p in node.children:
                w = _where(path, p)
                if p.name == "Line":
                    geo.fixed.append(_Item(_numbers(w, p.text, 4, "a fixed line (x1 y1 x2 y2)"), w))
                elif p.name == "Point":
                    x, y = _numbers(w, p.text, 2, "a fixed point (x y)")
                    geo.fixed.append(_Item((x, y, x, y), w))
                else:
                    raise SceneError(f"{w}: expected <Point> or <Line> in <Fixedpointlist>")
        elif node.name in points:
            for p in node.children:
                w = _where(path, p)
                if p.name != "Point":
                    raise SceneError(f"{w}: expected <Point> in <{node.name}>")
                points[node.name].append(_Item(_numbers(w, p.text, 2, "a point (x y)"), w))
        elif node.name == "Boltlist":
            for b in node.children:
                w = _where(path, b)
                if b.name != "Bolt":
                    raise SceneError(f"{w}: expected <Bolt> in <Boltlist>")
                geo.bolts.append(_Item(_numbers(w, b.text, 4, "a bolt (x1 y1 x2 y2)"), w))
        elif node.name == "Matlinelist":
            for m in node.children:
                w = _where(path, m)
                if m.name != "Line":
                    raise SceneError(f"{w}: expected <Line> in <Matlinelist>")
                geo.matlines.append(_Item(_numbers(w, m.text, 4, "a material line (x1 y1 x2 y2)"), w,
                                          _int_attr(w, m, "type")))
        elif node.name in ("Seismicpointlist", "Boundlist"):
            raise SceneError(f"{where}: not supported (no jaxdda equivalent; ntdda itself does not use <Boundlist>)")
    return geo


class _Tokens:
    """Whitespace-separated numbers with their line numbers, read the way fscanf does."""

    def __init__(self, path: Path):
        self.path = path
        self.items = [(tok, n) for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
                      for tok in line.split()]
        self.k = 0

    def number(self, what: str, integer: bool = False):
        if self.k >= len(self.items):
            last = self.items[-1][1] if self.items else 1
            raise SceneError(f"{self.path}, line {last}: the file ends before {what}")
        tok, line = self.items[self.k]
        self.k += 1
        try:
            value = int(tok) if integer else float(tok)
        except ValueError:
            kind = "an integer" if integer else "a number"
            raise SceneError(f"{self.path}, line {line}: {what} must be {kind}, got {tok!r}") from None
        if not integer and not math.isfinite(value):
            raise SceneError(f"{self.path}, line {line}: {what} must be finite, got {tok!r}")
        return value

    def row(self, what: str, names: str) -> _Item:
        line = self.items[self.k][1] if self.k < len(self.items) else None
        values = tuple(self.number(f"field '{n}' of {what}") for n in names.split())
        return _Item(values, f"{self.path}, line {line}: {what}")

    def count(self, what: str) -> int:
        n = self.number(what, integer=True)
        if n < 0:
            raise SceneError(f"{self.path}, line {self.items[self.k - 1][1]}: {what} must be >= 0, got {n}")
        return n


def _geometry_plain(path: Path) -> _Geometry:
    geo, t = _Geometry(str(path)), _Tokens(path)
    t.number("the edge-node distance e00")
    nj = t.count("the number of joints")
    t.count("the number of boundary lines")
    nm, nb = t.count("the number of material lines"), t.count("the number of bolts")
    nf, nl, nmeas, nh = (t.count(f"the number of {k} points") for k in ("fixed", "load", "measured", "hole"))
    if nb:
        raise SceneError(f"{path}: {nb} bolts: ntdda's plain-format reader reads no bolt records (\"Rock bolts are "
                         "not yet implemented\"), so their layout cannot be established; use the DDAML format")
    for k in range(nj):
        item = t.row(f"joint {k + 1}", "x1 y1 x2 y2 type")
        geo.joints.append(_joint_type(item))
    for k in range(nm):
        item = t.row(f"material line {k + 1}", "x1 y1 x2 y2 material")
        geo.matlines.append(_joint_type(item))
    geo.fixed += [t.row(f"fixed line {k + 1}", "x1 y1 x2 y2") for k in range(nf)]
    geo.loads += [t.row(f"load point {k + 1}", "x y") for k in range(nl)]
    geo.measured += [t.row(f"measured point {k + 1}", "x y") for k in range(nmeas)]
    geo.holes += [t.row(f"hole point {k + 1}", "x y") for k in range(nh)]
    return geo


def _joint_type(item: _Item) -> _Item:
    *xy, kind = item.values
    if kind != int(kind):
        raise SceneError(f"{item.where}: the type must be an integer, got {kind}")
    return _Item(tuple(xy), item.where, int(kind))


def _analysis_ddaml(path: Path) -> _Analysis:
    ana = _Analysis(str(path))
    section = _section(path, _parse_xml(path), "Analysis")
    for node in section.children:
        where = _where(path, node)
        if node.name == "Analysistype":
            ana.dynamic = 1.0 if _attr(where, node, "type") == "dynamic" else 0.0
        elif node.name == "Numtimesteps":
            ana.steps = _int_attr(where, node, "timesteps")
        elif node.name == "Maxtimestep":
            ana.dt = _float_attr(where, node, "maxtimestep")
        elif node.name == "Planestrain":
            ana.plane_strain = _attr(where, node, "flag") == "yes"
        elif node.name == "Blockmaterial":
            ana.materials.append(_block_material(where, node))
        elif node.name == "Jointproperties":
            values = {}
            for child in node.children:
                if child.name in ("Friction", "Cohesion", "Tensile"):
                    values[child.name] = _numbers(_where(path, child), child.text, 1, child.name)[0]
            for name in ("Friction", "Cohesion", "Tensile"):
                if name not in values:
                    raise SceneError(f"{where}: <{name}> is missing")
            ana.joints.append((values["Friction"], values["Cohesion"], values["Tensile"], where))
        elif node.name == "Loadpointlist":
            for lp in node.children:
                w = _where(path, lp)
                if lp.name != "Loadpoint":
                    raise SceneError(f"{w}: expected <Loadpoint> in <Loadpointlist>")
                n = _int_attr(w, lp, "numpoints")
                if n < 2:
                    raise SceneError(f"{w}: attribute 'numpoints' must be >= 2 (ntdda: \"2 or more load points are "
                                     f"required\"), got {n}")
                records = [r for r in lp.text.split(";") if r.strip()]
                if len(records) != n:
                    raise SceneError(f"{w}: numpoints=\"{n}\" but {len(records)} records 't fx fy;'")
                rows = [_numbers(w, r, 3, f"record {k + 1} (t fx fy)") for k, r in enumerate(records)]
                ana.loads.append(_Item(tuple(rows), w))
        elif node.name == "Boltproperties":
            if ana.bolt is None:  # bolt_init_materials gives every bolt the first
                ana.bolt = _numbers(where, node.text, 3, "bolt properties (stiffness strength pretension)") + (where,)
        elif node.name == "Timehistory":
            raise SceneError(f"{where}: not supported (an earthquake record file; no jaxdda equivalent)")
    if ana.steps is None:
        raise SceneError(f"{path}: <Numtimesteps timesteps=...> is missing")
    if ana.dt is None:
        raise SceneError(f"{path}: <Maxtimestep maxtimestep=...> is missing")
    return ana


def _block_material(where: str, node: _Node) -> dict:
    found = {}
    sizes = {"Unitmass": 1, "Unitweight": 1, "Youngsmod": 1, "Poissonratio": 1, "Damping": 1, "Istress": 3,
             "Istrain": 3, "Ivelocity": 3}
    for child in node.children:
        if child.name in sizes:
            found[child.name] = _numbers(f"{where[:where.rfind(', line')]}, line {child.line}: <{child.name}>",
                                         child.text, sizes[child.name], child.name)
    for name in ("Unitmass", "Unitweight", "Youngsmod", "Poissonratio"):
        if name not in found:
            raise SceneError(f"{where}: <{name}> is missing")
    zero = (0.0, 0.0, 0.0)
    return {"mass": found["Unitmass"][0], "weight": found["Unitweight"][0], "young": found["Youngsmod"][0],
            "poisson": found["Poissonratio"][0], "damping": found.get("Damping", (0.0,))[0],
            "stress": found.get("Istress", zero), "strain": found.get("Istrain", zero),
            "velocity": found.get("Ivelocity", zero), "where": where}


def _analysis_plain(path: Path) -> _Analysis:
    ana, t = _Analysis(str(path), plain=True), _Tokens(path)
    kind = t.number("the analysis type", integer=True)
    if kind not in (0, 1):
        raise SceneError(f"{path}, line {t.items[t.k - 1][1]}: the analysis type must be 0 (static) or 1 "
                         f"(dynamic), got {kind}")
    ana.dynamic = float(kind)
    ana.steps = t.count("the number of time steps")
    nb, nj = t.count("the number of block materials"), t.count("the number of joint materials")
    t.number("the maximum displacement ratio")
    ana.dt = t.number("the maximum time step")
    for k in range(nb):
        item = t.row(f"block material {k + 1}", "ma we e0 u0 s11 s22 s12 t11 t22 t12 vx vy vr")
        v = item.values
        ana.materials.append({"mass": v[0], "weight": v[1], "young": v[2], "poisson": v[3], "damping": 0.0,
                              "stress": v[4:7], "strain": v[7:10], "velocity": v[10:13], "where": item.where})
    for k in range(nj):
        item = t.row(f"joint material {k + 1}", "friction-angle cohesion tension")
        ana.joints.append(item.values + (item.where,))
    return ana


# -- geometry: blocks and points -------------------------------------------------------------
def _domain_scale(joints) -> float:
    """w0 of computeDomainscale (src/geometrydata.c)."""
    xy = np.array([j.values for j in joints]).reshape(-1, 2)
    width, height = np.ptp(xy[:, 0]) / 2, np.ptp(xy[:, 1]) / 2
    w0 = height if width <= 1.3 * height else width / 1.3
    return 1.02 * float(w0)


def _crossing(p, q, a, b, tol):
    """Parameter s along p->q where the closed segments p-q and a-b cross, or None
    (parallel segments do not cross, as in ntdda's lns)."""
    r, e = q - p, b - a
    d = r[0] * e[1] - r[1] * e[0]
    if abs(d) <= 1e-12 * np.linalg.norm(r) * np.linalg.norm(e):
        return None
    ap = a - p
    s = (ap[0] * e[1] - ap[1] * e[0]) / d
    u = (ap[0] * r[1] - ap[1] * r[0]) / d
    es, eu = tol / np.linalg.norm(r), tol / np.linalg.norm(e)
    if -es <= s <= 1 + es and -eu <= u <= 1 + eu:
        return s
    return None


def _edges(verts):
    return zip(verts, np.roll(verts, -1, axis=0))


def _block_of(blocks, point) -> int | None:
    p = np.asarray(point, float)
    for i, b in enumerate(blocks):
        on_edge = any(cutting._segment_distance(p, a, c) == 0.0 for a, c in _edges(b.vertices))
        if on_edge or cutting._inside(p, b.vertices):
            return i
    return None


def _cut(geo: _Geometry):
    if not geo.joints:
        raise SceneError(f"{geo.path}: no joint lines, so no blocks")
    lines = np.array([j.values for j in geo.joints], float).reshape(-1, 2, 2)
    for j, seg in zip(geo.joints, lines):
        if np.array_equal(seg[0], seg[1]):
            raise SceneError(f"{j.where}: the joint has zero length")
    lo, hi = lines.reshape(-1, 2).min(0), lines.reshape(-1, 2).max(0)
    pad = 0.1 * float(max(hi - lo)) + 1.0
    (x0, y0), (x1, y1) = lo - pad, hi + pad
    box = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    try:
        faces = cutting.cut_blocks(box, lines)
    except SceneError as err:
        raise SceneError(f"{geo.path}: {err}") from None
    blocks = [b for b in faces if not np.any(b.edge_lines == cutting.BOUNDARY)]
    # dc16: a block inside another block is dropped
    inner = [i for i, b in enumerate(blocks)
             if any(j != i and cutting._inside(cutting._interior_point(b.vertices), c.vertices)
                    for j, c in enumerate(blocks))]
    blocks = [b for i, b in enumerate(blocks) if i not in inner]
    for hole in geo.holes:  # dc11: a block holding a hole point is deleted
        k = _block_of(blocks, hole.values)
        if k is None:
            raise SceneError(f"{hole.where}: the hole point {list(hole.values)} lies in no block")
        blocks.pop(k)
    if not blocks:
        raise SceneError(f"{geo.path}: the joint lines enclose no block")
    return blocks


def _materials_of(geo: _Geometry, blocks, tol) -> list[int]:
    """dc13: material numbers of the blocks."""
    material = [1] * len(blocks)
    for line in geo.matlines:
        p, q = np.array(line.values[:2]), np.array(line.values[2:])
        hit = False
        if np.linalg.norm(q - p) > 0:
            for i, b in enumerate(blocks):
                if any(_crossing(p, q, a, c, tol) is not None for a, c in _edges(b.vertices)):
                    material[i], hit = line.kind, True
        if not hit:
            k = _block_of(blocks, p)
            if k is not None:
                material[k] = line.kind
    return material


def _fixed_points(geo: _Geometry, blocks, w0, tol) -> list[tuple[int, list[float], str]]:
    """dc10: fixed points from fixed lines and points: (block, point, where)."""
    out = []
    for item in geo.fixed:
        p, q = np.array(item.values[:2]), np.array(item.values[2:])
        made = []
        if np.abs(q - p).sum() > 1e-9 * w0:
            for i, b in enumerate(blocks):
                for a, c in _edges(b.vertices):
                    s = _crossing(p, q, a, c, tol)
                    if s is None:
                        continue
                    e = c - a
                    inward = np.array([-e[1], e[0]]) / np.linalg.norm(e)  # blocks are counter-clockwise
                    made.append((i, (p + s * (q - p) + 0.005 * w0 * inward).tolist(), item.where))
        if not made:
            k = _block_of(blocks, p)
            if k is None:
                raise SceneError(f"{item.where}: the fixed point {p.tolist()} lies in no block")
            made.append((k, p.tolist(), item.where))
        out += made
    return out


def _interface_lengths(blocks) -> dict[int, list[float]]:
    """Per joint line: the lengths of its interfaces (stretches where edges of two blocks,
    both made by that line, overlap) at t = 0."""
    by_line: dict[int, list] = {}
    for i, b in enumerate(blocks):
        for (a, c), line in zip(_edges(b.vertices), b.edge_lines):
            by_line.setdefault(int(line), []).append((i, a, c))
    out: dict[int, list[float]] = {}
    for line, edges in by_line.items():
        pairs: dict[tuple[int, int], float] = {}
        for m in range(len(edges)):
            i, a, c = edges[m]
            d = (c - a) / np.linalg.norm(c - a)
            for n in range(m + 1, len(edges)):
                j, a2, c2 = edges[n]
                if j == i:
                    continue
                s = sorted((float(np.dot(a2 - a, d)), float(np.dot(c2 - a, d))))
                overlap = min(float(np.linalg.norm(c - a)), s[1]) - max(0.0, s[0])
                if overlap > 1e-9 * float(np.linalg.norm(c - a)):
                    key = (min(i, j), max(i, j))
                    pairs[key] = pairs.get(key, 0.0) + overlap
        out[line] = list(pairs.values())
    return out


# -- the scene ---------------------------------------------------------------------------
def read_ntdda(geometry_path, analysis_path=None, *, tensile: bool = False) -> dict:
    """Read an ntdda geometry file (DDAML or plain text) and, optionally, its analysis file
    into a scene description dict (the scene-file schema of ``loader.scene_from_dict``).

    Blocks are the bounded faces of the joint lines, with their edges' joints named
    ``"joint<type>"`` and their materials ``"material<number>"``; see the module docstring
    for every rule and conversion and the ntdda function it follows. Without an analysis
    file the dict has no ``settings``, its ``materials`` and ``joints`` are empty and
    connectors and loads have no properties: the geometry only, to be completed.
    ``tensile=True`` imports the joints' tensile strength (ntdda ignores it).
    Errors are SceneErrors naming the file, line, element and field."""
    geo_path = Path(geometry_path)
    geo = _geometry_ddaml(geo_path) if _file_type(geo_path) == "ddaml" else _geometry_plain(geo_path)
    blocks = _cut(geo)
    w0 = _domain_scale(geo.joints)
    tol = 1e-9 * w0
    material = _materials_of(geo, blocks, tol)
    joint_type = {k: j.kind for k, j in enumerate(geo.joints)}
    scene = _geometry_scene(geo, blocks, material, joint_type, w0, tol)
    if analysis_path is None:
        scene["materials"], scene["joints"] = {}, {}
        return _ordered(scene)
    ana_path = Path(analysis_path)
    ana = _analysis_ddaml(ana_path) if _file_type(ana_path) == "ddaml" else _analysis_plain(ana_path)
    _check_defined(geo, ana, material, joint_type)
    materials, g = _materials(ana, material, scene["bodies"])
    joints = _joints(ana, blocks, joint_type, tensile)
    _load_histories(geo, ana, scene["loads"])
    _bolt_properties(geo, ana, scene["connectors"])
    scene["settings"] = {"dt": ana.dt, "steps": ana.steps, "gravity": [0.0, -g], "dynamic": ana.dynamic}
    scene["materials"], scene["joints"] = materials, joints
    return _ordered(scene)


def _geometry_scene(geo: _Geometry, blocks, material: list[int], joint_type: dict, w0: float, tol: float) -> dict:
    """The scene's geometry: its blocks as bodies, fixed, load and measured points, bolts."""
    def block_at(item: _Item, point, what: str) -> int:
        k = _block_of(blocks, point)
        if k is None:
            raise SceneError(f"{item.where}: the {what} {list(map(float, point))} lies in no block")
        return k

    connectors = []
    for bolt in geo.bolts:
        a, b = bolt.values[:2], bolt.values[2:]
        ka, kb = block_at(bolt, a, "bolt end"), block_at(bolt, b, "bolt end")
        if ka == kb:
            raise SceneError(f"{bolt.where}: both ends of the bolt lie in block {ka}; a bolt joins two blocks")
        connectors.append({"type": "spring", "body_a": ka, "body_b": kb, "at_a": list(a), "at_b": list(b)})
    return {
        "name": Path(geo.path).stem,
        "bodies": [{"type": "polygon", "vertices": b.vertices.tolist(), "material": f"material{material[i]}",
                    "joints": [f"joint{joint_type[int(line)]}" for line in b.edge_lines], "fixed": False}
                   for i, b in enumerate(blocks)],
        "fixed_points": [{"body": k, "at": at} for k, at, _ in _fixed_points(geo, blocks, w0, tol)],
        "loads": [{"body": block_at(p, p.values, "load point"), "at": list(p.values)} for p in geo.loads],
        "measured_points": [{"body": block_at(p, p.values, "measured point"), "at": list(p.values)}
                            for p in geo.measured],
        "connectors": connectors,
    }


def _check_defined(geo: _Geometry, ana: _Analysis, material: list[int], joint_type: dict) -> None:
    """Every block material and joint type the geometry uses is defined in the analysis."""
    for m in sorted(set(material)):
        if not 1 <= m <= len(ana.materials):
            where = next((line.where for line in geo.matlines if line.kind == m), geo.path)
            raise SceneError(f"{where}: block material {m} is not defined in {ana.path} "
                             f"({len(ana.materials)} <Blockmaterial> / block materials)")
    for t in sorted(set(joint_type.values())):
        if not 1 <= t <= len(ana.joints):
            where = next(j.where for j in geo.joints if j.kind == t)
            raise SceneError(f"{where}: joint type {t} is not defined in {ana.path} "
                             f"({len(ana.joints)} <Jointproperties> / joint materials)")


def _materials(ana: _Analysis, material: list[int], bodies: list[dict]) -> tuple[dict, float]:
    """The block materials and the gravity their unit weights give (one for all the used
    ones); each body's initial stress and velocity from its material (set on ``bodies``)."""
    used = set(material)
    g = None
    materials = {}
    for m, mat in enumerate(ana.materials, 1):
        w = mat["where"]
        if mat["mass"] <= 0:
            raise SceneError(f"{w}: field 'Unitmass' (unit mass) must be > 0, got {mat['mass']}")
        if mat["young"] <= 0:
            raise SceneError(f"{w}: field 'Youngsmod' must be > 0, got {mat['young']}")
        ratio = mat["weight"] / mat["mass"]
        if m in used:
            if g is None:
                g = (ratio, w)
            elif not math.isclose(ratio, g[0], rel_tol=1e-6, abs_tol=1e-12):
                raise SceneError(f"{w}: unit weight / unit mass = {ratio:.6g} differs from {g[0]:.6g} "
                                 f"({g[1]}): one gravity cannot give both block materials their weight")
            if mat["damping"] != 0:
                warnings.warn(f"{w}: damping {mat['damping']} is not imported (no block damping in jaxdda)")
            if any(mat["strain"]):
                warnings.warn(f"{w}: initial strain {list(mat['strain'])} is not imported")
        # ntdda has no restitution and its contacts do not rebound: e = 0 (jaxdda's default is 1)
        entry = {"density": mat["mass"], "young": mat["young"], "poisson": mat["poisson"], "restitution": 0.0}
        if ana.plane_strain:
            entry["plane"] = "strain"
        materials[f"material{m}"] = entry
    for i, body in enumerate(bodies):
        mat = ana.materials[material[i] - 1]
        if any(mat["stress"]):
            body["stress"] = list(mat["stress"])
        if any(mat["velocity"][:2]):
            body["velocity"] = list(mat["velocity"][:2])
        if mat["velocity"][2]:
            body["angular_velocity"] = mat["velocity"][2]
    return materials, g[0]


def _joints(ana: _Analysis, blocks, joint_type: dict, tensile: bool) -> dict:
    """The joint materials: friction angle to coefficient, cohesion (and tensile strength)
    as a force per interface of the joint type's mean length."""
    lengths = _interface_lengths(blocks)
    joints = {}
    for t, (phi, cohesion, tension, w) in enumerate(ana.joints, 1):
        if not 0 <= phi < 90:
            raise SceneError(f"{w}: field 'Friction' (friction angle, degrees) must be in [0, 90), got {phi}")
        if cohesion < 0 or tension < 0:
            raise SceneError(f"{w}: fields 'Cohesion' and 'Tensile' must be >= 0, got {cohesion}, {tension}")
        lines = [k for k, kind in joint_type.items() if kind == t]
        shared = [L for k in lines for L in lengths.get(k, [])]
        edges = [float(np.linalg.norm(c - a)) for b in blocks for (a, c), line in zip(_edges(b.vertices), b.edge_lines)
                 if int(line) in lines]
        length = float(np.mean(shared)) if shared else (float(np.mean(edges)) if edges else 0.0)
        joints[f"joint{t}"] = {"friction": math.tan(math.radians(phi)), "cohesion": cohesion * length,
                               "tensile": tension * length if tensile else 0.0, "restitution": 0.0}
    return joints


def _load_histories(geo: _Geometry, ana: _Analysis, loads: list[dict]) -> None:
    """Each load point's force history (set on ``loads``); the plain format has none."""
    if ana.plain:
        if geo.loads:
            warnings.warn(f"{ana.path}: the plain analysis format has no load histories; ntdda applies no force at "
                          f"the {len(geo.loads)} load points")
        for load in loads:
            load["history"] = [[0.0, 0.0, 0.0]]
        return
    if len(ana.loads) != len(geo.loads):
        raise SceneError(f"{ana.path}: {len(ana.loads)} <Loadpoint> histories for the {len(geo.loads)} load "
                         f"points of {geo.path}")
    end = ana.steps * ana.dt
    for load, item in zip(loads, ana.loads):
        rows = [list(r) for r in item.values]
        times = [r[0] for r in rows]
        if any(b < a for a, b in zip(times, times[1:])):
            raise SceneError(f"{item.where}: the record times must not decrease, got {times}")
        (t0, *f0), (t1, *f1) = rows[-2], rows[-1]
        if t1 < end and t1 > t0 and f0 != f1:  # ntdda extrapolates the last segment (df09)
            rows.append([end] + [a + (b - a) * (end - t0) / (t1 - t0) for a, b in zip(f0, f1)])
        load["history"] = rows


def _bolt_properties(geo: _Geometry, ana: _Analysis, connectors: list[dict]) -> None:
    """The bolts' stiffness and pretension (set on ``connectors``)."""
    if not connectors:
        return
    if ana.bolt is None:
        raise SceneError(f"{ana.path}: {len(connectors)} bolts in {geo.path} but no <Boltproperties>")
    stiffness, _, pretension, w = ana.bolt
    if stiffness <= 0:
        raise SceneError(f"{w}: the bolt stiffness must be > 0, got {stiffness}")
    for conn in connectors:
        conn["stiffness"], conn["pretension"] = stiffness, pretension


def _ordered(scene: dict) -> dict:
    keys = ("name", "settings", "materials", "joints", "bodies", "fixed_points", "loads", "measured_points",
            "connectors")
    return {k: scene[k] for k in keys if k in scene}
