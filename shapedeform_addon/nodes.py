# SPDX-License-Identifier: GPL-3.0-or-later
"""The Geometry Nodes group that deforms a bound object through its rig's cage.

The cage is a triangle mesh of the solver's graph, posed by the rig; its point attribute
``sd_rest`` holds each point's rest position. The group maps every point it receives (mesh
vertices, curve control points and both Bezier handles, grease-pencil stroke points of every
drawing) by the affine map of the nearest rest triangle: the map that takes that triangle's
rest corners to its posed corners and keeps the distance from the plane. Inside the outline
this is the barycentric interpolation of the posed cage; outside it, the nearest triangle's map
carried on, so points off the cage (outside the outline, lifted by a shape key) move with the
part they belong to instead of sticking to its border. (``solver.bind`` blends the maps of the
triangles along the nearest stretch of boundary instead; a node tree cannot afford that per
point, so here a point in a notch between two parts follows the nearer one.)

Rig space: the cage's points are in the space the rig was bound in (the bound object's local
space at bind time). The cage object is parented to the bound object, so Apply Transform on it
keeps the cage's world place by changing the cage's own transform: the group maps the cage into
the deformed object's space with ``inverse(object) @ cage``, both world matrices (the object's
from Self Object). A duplicate that follows the rig has a cage object of its own, sharing the
rig's cage mesh and parented to it as the rig's cage is to the owner (``duplicates.follow``):
Apply Transform on either object keeps both in place, and nothing but its own modifier points
at it (a modifier naming its own object kept a deleted duplicate alive in the file).

Finding each point's triangle is most of the cost (a nearest-triangle search per point takes
about 85% of an evaluation of a 50,000-vertex mesh). Points whose projection lies inside the
cage, nearly all of them, are found instead by Sample UV Surface, whose reverse-UV grid is a
cheaper lookup: the cage gets a UV map, its rest points in the plane scaled to the unit square,
and each point samples the cage's displacement (posed minus rest) at its own UV, which is the
same map (barycentric in the plane, heights kept). Only the points it misses (off the outline)
and Bezier handles take the nearest-triangle search.

Where islands of a mesh that is its own graph overlap in the plane (a cut-out puppet's arm over
its body), a place alone cannot tell them apart. Bind gives such a mesh's vertices their island
(``ISLAND``, a hidden integer point attribute, also on the cage's points), which Blender keeps
through Edit Mode, Separate, shape keys and ``Refine``: the cage's UVs put each island in a tile
of its own, two units from the next, and a point samples its island's tile; a point its island's
part misses takes the nearest triangle of that island (Sample Nearest Surface by group). A point
of no island (a rig bound by an older version, a vertex added since, a mesh joined in) is looked
up by its place (in an island rig, by the nearest triangle of any island); one that is the
cage's point of its own index, at its rest place (such a rig unedited), takes that point's
displacement. A rig whose cage has no islands (every other rig, and one bound by an older
version) takes a branch of the group that never reads them, so it pays nothing for them. The
group's output has no islands, cage or none: they are the rig's, not the shape's.

Grease pencil's ``Stroke Order`` draws the strokes lying on a folded-over part after the others
in their layer: a ray from behind through the posed cage finds the lowest layer under each
point, and a stroke most of whose points lie higher sorts last (stably, so every other stroke
keeps the drawing's order).

A missing cage (deleted by hand) leaves the geometry as it is. The ``Refine`` input (0 by
default) subdivides a mesh's faces before mapping: a long thin face spanning a bent stretch
otherwise keeps straight edges and can flip although the map under it does not fold. It
subdivides no further than leaves the mesh ``REFINE_BUDGET`` faces (what plays live).

The group is built from Python (no asset file to keep in step) and rebuilt when an older
extension's group is found (``VERSION``); the modifiers that use it keep their inputs.
"""

import bpy

from ..solver.rigging.outline import REFINE_BUDGET
from . import compat

GROUP_NAME = "Shape Deform"
VERSION = 22
VERSION_KEY = "shapedeform_version"
REST = "sd_rest"
POSED = "sd_posed"  # only inside the group, on the cage
# An integer point attribute: on the cage, each point's island number (from a first number of
# the rig's own, ``rig_format.island_numbers``); on a mesh that is its own graph in several
# islands, each vertex's (hidden: the name starts with a dot). 0, missing, or outside the
# cage's numbers: not known (a vertex added since binding, a rigged puppet joined in).
ISLAND = ".sd_island"
# The name of a boolean attribute naming what the rig deforms (grease-pencil layers chosen at
# bind time, on the LAYER domain), given to each modifier (``RIGGED_INPUT``): objects sharing
# their data each have their own; everything is deformed when it is missing or the name empty.
# A modifier made by version 1 of the group, which had no such input, reads ``RIGGED``.
RIGGED = "sd_rigged"
CAGE_INPUT, RIGGED_INPUT = "Cage", "Rigged Layers"
# Up to version 9 the group read the deformed object's space from this input instead of Self
# Object; only a linked library's group can still have it (``duplicates.follow``).
LEGACY_OWNER_INPUT = "Owner"
REFINE_INPUT, ORDER_INPUT = "Refine", "Stroke Order"
REFINE_MOST = 6  # the most times Refine subdivides
CURVE_TYPE_BEZIER = 2  # the built-in curve_type attribute's value for Bezier curves
KEPT_INPUTS = (CAGE_INPUT, RIGGED_INPUT, REFINE_INPUT, ORDER_INPUT)


def node_group():
    """The current file's own deformer group, built (or rebuilt from an older version) if needed.

    Ours is known by its version stamp, not its name: a group of the user's called "Shape
    Deform" is left alone (ours is then "Shape Deform.001"). A linked library's group is never
    used: it cannot be saved here, and when the library rebuilds it at a new version its inputs
    change identifiers under this file's modifiers."""
    ours = [g for g in bpy.data.node_groups
            if g.library is None and g.bl_idname == "GeometryNodeTree" and VERSION_KEY in g]
    for group in ours:
        if group.get(VERSION_KEY) == VERSION:
            return group
    group = ours[0] if ours else bpy.data.node_groups.new(GROUP_NAME, "GeometryNodeTree")
    _rebuild(group)
    return group


def _rebuild(group):
    """Build ``group`` anew at this version; the modifiers using it keep their inputs' values."""
    # Rebuilding gives the inputs new identifiers: carry each modifier's values over by name.
    users = [(o, m) for o in bpy.data.objects for m in o.modifiers if m.type == "NODES" and m.node_group == group]
    old = input_identifiers(group)
    kept = [(o, m, {name: compat.modifier_input(m, key) for name, key in old.items() if name in KEPT_INPUTS})
            for o, m in users]  # not the geometry (nor version 9's Owner: Self Object stands for it)
    _build(group)
    group[VERSION_KEY] = VERSION
    new = input_identifiers(group)
    for _obj, modifier, values in kept:
        for name, value in values.items():
            if name in new and value is not None:
                compat.set_modifier_input(modifier, new[name], value)
        if RIGGED_INPUT not in old:
            compat.set_modifier_input(modifier, new[RIGGED_INPUT], RIGGED)


def upgrade():
    """Rebuild the open file's groups an older version made (a file opened, the extension
    enabled), appended copies ("Shape Deform.001") included: the rest of the extension reads
    the current group's inputs (a duplicate's own cage means nothing to version 9, which placed
    every cage in its owner's space). A linked library's group stays as the library has it."""
    for group in list(bpy.data.node_groups):
        if group.library is None and group.bl_idname == "GeometryNodeTree" and VERSION_KEY in group \
                and group.get(VERSION_KEY) != VERSION:
            _rebuild(group)
    _unlink_library_groups()


def _unlink_library_groups():
    """Give this file's own rigs this file's group where an earlier version gave them a linked
    library's (it looked the group up by name), inputs carried over by name; a cage whose value
    the library's rebuilt group lost is the object's own."""
    local = None
    for obj in bpy.data.objects:
        if obj.library is not None or obj.override_library is not None:
            continue
        for modifier in obj.modifiers:
            linked = modifier.node_group if modifier.type == "NODES" else None
            if linked is None or linked.library is None or VERSION_KEY not in linked:
                continue
            local = local or node_group()
            values = {name: compat.modifier_input(modifier, key) for name, key in input_identifiers(linked).items()
                      if name in KEPT_INPUTS}
            if values.get(CAGE_INPUT) is None:
                values[CAGE_INPUT] = obj.shapedeform.cage
            modifier.node_group = local
            new = input_identifiers(local)
            for name, value in values.items():
                if name in new and value is not None:
                    compat.set_modifier_input(modifier, new[name], value)


def input_identifiers(group):
    """{input name: identifier} of the group's inputs (modifier keys are the identifiers)."""
    return {item.name: item.identifier for item in group.interface.items_tree
            if item.item_type == "SOCKET" and item.in_out == "INPUT"}


class _Builder:
    """Adds nodes to a group and wires them: ``node(idname, inputs, **properties)``."""

    def __init__(self, group):
        self.group = group
        self.x = 0

    def node(self, idname, inputs=(), **properties):
        node = self.group.nodes.new(idname)
        for name, value in properties.items():
            setattr(node, name, value)
        for key, value in (inputs.items() if isinstance(inputs, dict) else enumerate(inputs)):
            if value is None:
                continue
            socket = node.inputs[key]
            if isinstance(value, bpy.types.NodeSocket):
                self.group.links.new(value, socket)
            else:
                socket.default_value = value
        node.location = (self.x, 0)
        self.x += 180
        return node

    def math(self, operation, *inputs):
        return self.node("ShaderNodeVectorMath", inputs, operation=operation).outputs[0]

    def columns_matrix(self, *columns):
        """A 4x4 affine matrix from three vector columns and a translation column."""
        inputs = {}
        for c, column in enumerate(columns):
            xyz = self.node("ShaderNodeSeparateXYZ", [column])
            for r in range(3):
                inputs[4 * c + r] = xyz.outputs[r]
        return self.node("FunctionNodeCombineMatrix", inputs).outputs[0]


def _build(group):
    """Fill ``group`` with the deformer: the stages below, in the order the geometry meets them."""
    group.nodes.clear()
    _interface(group)
    b = _Builder(group)
    given = b.node("NodeGroupInput")
    geometry = b.node("GeometryNodeSubdivideMesh", {"Mesh": given.outputs[0],
                                                     "Level": _refine_level(b, given)}).outputs[0]
    cage = _Cage(b, given.outputs[CAGE_INPUT])
    selection = _rigged_selection(b, given.outputs[RIGGED_INPUT])
    # Drawings and meshes seldom have a Bezier curve: theirs is a path that never reads handles
    # (setting a grease-pencil monkey's handles took a third of its evaluation, poly strokes all).
    has_bezier = _has_bezier_curves(b, geometry)
    bezier = _on_bezier_curves(b, selection)
    curves, left, right, point = _map_bezier_handles(b, cage, geometry, bezier)
    handled = b.node("GeometryNodeSwitch", {"Switch": has_bezier, "False": geometry, "True": curves},
                     input_type="GEOMETRY").outputs[0]
    mapped, on_cage = _map_points(b, cage, handled, selection)
    with_handles = _set_bezier_handles(b, cage, mapped, bezier, left, right, point)
    moved = b.node("GeometryNodeSwitch", {"Switch": has_bezier, "False": mapped, "True": with_handles},
                   input_type="GEOMETRY").outputs[0]
    ordered = _stroke_order(b, cage, moved, given.outputs[ORDER_INPUT], selection, on_cage)
    # No cage (deleted by hand, or no faces): the geometry passes unchanged.
    faces = b.node("GeometryNodeAttributeDomainSize", {"Geometry": cage.geometry}, component="MESH")
    has_cage = b.node("FunctionNodeCompare", {"A": faces.outputs["Face Count"], "B": 0},
                      data_type="INT", operation="GREATER_THAN").outputs[0]
    switch = b.node("GeometryNodeSwitch", {"Switch": has_cage, "False": given.outputs[0], "True": ordered},
                    input_type="GEOMETRY")
    # The islands are the rig's: a modifier applied, or a mesh exported with modifiers, has none,
    # with its cage or without.
    output = b.node("GeometryNodeRemoveAttribute", {"Geometry": switch.outputs[0], "Name": ISLAND}).outputs[0]
    b.node("NodeGroupOutput", {0: output})


def _refine_level(b, given):
    """The Refine input, lowered as far as keeps the subdivided mesh within ``REFINE_BUDGET``
    faces (a text typed longer after Bind chose its Refine, a Refine raised on a dense mesh)."""
    faces = b.node("GeometryNodeAttributeDomainSize", {"Geometry": given.outputs[0]}, component="MESH")
    count = b.node("ShaderNodeMath", [faces.outputs["Face Count"], 1.0], operation="MAXIMUM").outputs[0]
    share = b.node("ShaderNodeMath", [REFINE_BUDGET, count], operation="DIVIDE").outputs[0]
    levels = b.node("ShaderNodeMath", [share, 4.0], operation="LOGARITHM").outputs[0]
    affordable = b.node("ShaderNodeMath", [b.node("ShaderNodeMath", [levels], operation="FLOOR").outputs[0], 0.0],
                        operation="MAXIMUM").outputs[0]
    return b.node("ShaderNodeMath", [given.outputs[REFINE_INPUT], affordable], operation="MINIMUM").outputs[0]


def _interface(group):
    """The group's inputs and output, with the descriptions the modifier shows."""
    group.interface.clear()
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket(CAGE_INPUT, in_out="INPUT", socket_type="NodeSocketObject")
    group.interface.new_socket(RIGGED_INPUT, in_out="INPUT", socket_type="NodeSocketString")
    refine = group.interface.new_socket(REFINE_INPUT, in_out="INPUT", socket_type="NodeSocketInt")
    refine.description = ("Subdivide a mesh's faces this many times before deforming it, so long thin "
                          "faces (text, n-gon fills) bend instead of folding; 0 keeps the mesh as it is")
    refine.default_value, refine.min_value, refine.max_value = 0, 0, REFINE_MOST
    order = group.interface.new_socket(ORDER_INPUT, in_out="INPUT", socket_type="NodeSocketBool")
    order.description = ("Grease pencil: in each layer, draw the strokes lying on a part the pose folds over "
                         "another after the others, which keep their order. While a stroke is moved, each layer "
                         "draws as layers of its name and settings, in no layer group, with only the current "
                         "frame's drawing, keyed at frame 0 (onion skins and drawings before frame 0 vanish, "
                         "masks find one of the copies). Bind turns it on where renders lose nothing by it")
    order.default_value = False
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")


class _Cage:
    """The cage in the deformed object's space, and the fields every stage samples it by.

    Attributes (node sockets): ``geometry`` the cage as its object gives it; ``rest`` the cage
    at rest, its posed points kept in the ``POSED`` attribute; ``position`` and ``posed`` the
    position and posed-position fields; ``face_map`` each triangle's linear map, rest edges to
    posed edges with the rest normal kept (so heights above the plane are kept), applied about
    ``face_rest_corner`` (taken to ``face_posed_corner``); ``normal`` the rest plane's normal; ``span`` the rest cage's extent in its plane, and ``corner`` its
    lowest corner there (the UV square's origin).
    """

    def __init__(self, b, cage_object):
        self.b = b
        cage = b.node("GeometryNodeObjectInfo", {"Object": cage_object}, transform_space="ORIGINAL")
        deformed = b.node("GeometryNodeSelfObject").outputs[0]
        owner = b.node("GeometryNodeObjectInfo", {"Object": deformed}, transform_space="ORIGINAL")
        inverse_owner = b.node("FunctionNodeInvertMatrix", [owner.outputs["Transform"]]).outputs[0]
        to_object = b.node("FunctionNodeMatrixMultiply", [inverse_owner, cage.outputs["Transform"]]).outputs[0]
        self.geometry = cage.outputs["Geometry"]
        position = self.position = b.node("GeometryNodeInputPosition").outputs[0]
        rest = b.node("GeometryNodeInputNamedAttribute", {"Name": REST}, data_type="FLOAT_VECTOR").outputs[0]
        posed_here = b.node("FunctionNodeTransformPoint", [position, to_object]).outputs[0]
        rest_here = b.node("FunctionNodeTransformPoint", [rest, to_object]).outputs[0]
        stored = b.node("GeometryNodeStoreNamedAttribute",
                        {"Geometry": self.geometry, "Name": POSED, "Value": posed_here},
                        data_type="FLOAT_VECTOR", domain="POINT").outputs[0]
        self.rest = b.node("GeometryNodeSetPosition", {"Geometry": stored, "Position": rest_here}).outputs[0]
        self.posed = b.node("GeometryNodeInputNamedAttribute", {"Name": POSED}, data_type="FLOAT_VECTOR").outputs[0]
        self._face_maps()
        self._plane()
        self._islands()

    def _face_maps(self):
        """Each triangle's linear map (rest edges to posed edges, the rest normal kept), with
        its first corner at rest and posed: :meth:`mapped` applies it about that corner, so its
        rounding scales with a point's distance from the triangle, not from the object's origin
        (a drawing 1e6 from its origin, applied as one affine map in float32, was thrown 6e4)."""
        b, position, posed = self.b, self.position, self.posed
        rest_corners, posed_corners = [], []
        for k in range(3):
            corner = b.node("GeometryNodeCornersOfFace", {"Sort Index": k}).outputs["Corner Index"]
            vertex = b.node("GeometryNodeVertexOfCorner", [corner]).outputs[0]
            for field, corners in ((position, rest_corners), (posed, posed_corners)):
                corners.append(b.node("GeometryNodeSampleIndex", {"Geometry": self.rest, "Value": field, "Index": vertex},
                                      data_type="FLOAT_VECTOR", domain="POINT").outputs[0])
        e1, e2 = (b.math("SUBTRACT", r, rest_corners[0]) for r in rest_corners[1:])
        f1, f2 = (b.math("SUBTRACT", p, posed_corners[0]) for p in posed_corners[1:])
        normal = b.math("NORMALIZE", b.math("CROSS_PRODUCT", e1, e2))
        origin = (0.0, 0.0, 0.0)
        inverse_rest = b.node("FunctionNodeInvertMatrix", [b.columns_matrix(e1, e2, normal, origin)])
        linear = b.node("FunctionNodeMatrixMultiply", [b.columns_matrix(f1, f2, normal, origin),
                                                        inverse_rest.outputs["Matrix"]]).outputs[0]
        # A triangle flat to rounding has no map of its own: its corner's shift alone.
        identity = b.node("FunctionNodeCombineMatrix").outputs[0]
        self.face_map = b.node("GeometryNodeSwitch", {"Switch": inverse_rest.outputs["Invertible"],
                                                      "False": identity, "True": linear},
                               input_type="MATRIX").outputs[0]
        self.face_rest_corner, self.face_posed_corner = rest_corners[0], posed_corners[0]

    def _plane(self):
        # The rig's plane, turned onto XY, gives the UVs; the rest cage's first face has its
        # normal (every face has the same: the rest cage is flat).
        b = self.b
        self.normal = b.node("GeometryNodeSampleIndex",
                             {"Geometry": self.rest, "Value": b.node("GeometryNodeInputNormal").outputs[0], "Index": 0},
                             data_type="FLOAT_VECTOR", domain="FACE").outputs[0]
        self._onto_plane = b.node("FunctionNodeInvertRotation", [b.node(
            "FunctionNodeAlignRotationToVector", {"Vector": self.normal}, axis="Z").outputs[0]]).outputs[0]
        flat_cage = b.node("GeometryNodeSetPosition",
                           {"Geometry": self.rest, "Position": self.in_plane(self.position)}).outputs[0]
        box = b.node("GeometryNodeBoundBox", [flat_cage])
        self.corner = box.outputs["Min"]
        self.span = b.math("SUBTRACT", box.outputs["Max"], self.corner)

    def _islands(self):
        """``island``: a point's island of the cage, counted from 1 (its :data:`ISLAND` number
        less the cage's first, plus 1), on the cage and on the deformed geometry alike; 0 where
        it is not one of the cage's (unknown, another rig's, or the cage has none). ``tile``:
        where the island's UVs lie (:meth:`uv`). ``has_islands``: whether the cage has any (a
        boolean single value; none where Bind found one island, or an older version bound the
        rig)."""
        b = self.b
        given = b.node("GeometryNodeInputNamedAttribute", {"Name": ISLAND}, data_type="INT").outputs[0]
        numbers = b.node("GeometryNodeAttributeStatistic", {"Geometry": self.rest, "Attribute": given},
                         data_type="FLOAT", domain="POINT")
        first, last = numbers.outputs["Min"], numbers.outputs["Max"]
        self.has_islands = b.node("FunctionNodeCompare", {"A": last, "B": 0.5}, data_type="FLOAT",
                                  operation="GREATER_THAN").outputs[0]
        low = b.node("FunctionNodeCompare", {"A": given, "B": first}, data_type="FLOAT",
                     operation="GREATER_EQUAL").outputs[0]
        high = b.node("FunctionNodeCompare", {"A": given, "B": last}, data_type="FLOAT",
                      operation="LESS_EQUAL").outputs[0]
        listed = b.node("FunctionNodeBooleanMath", [low, high], operation="AND").outputs[0]
        listed = b.node("FunctionNodeBooleanMath", [listed, self.has_islands], operation="AND").outputs[0]

        def counted(number):  # from 1
            return b.node("ShaderNodeMath", [b.node("ShaderNodeMath", [number, first], operation="SUBTRACT").outputs[0],
                                             1.0], operation="ADD").outputs[0]

        self.island = b.node("ShaderNodeMath", [counted(given), listed], operation="MULTIPLY").outputs[0]
        count = counted(last)
        # Islands in a square of tiles two units apart (apart from the unit square of island
        # 0), near the origin: UVs keep float32's precision with hundreds of islands.
        columns = b.node("ShaderNodeMath", [b.node("ShaderNodeMath", [count, 1.0], operation="ADD").outputs[0]],
                         operation="SQRT").outputs[0]
        columns = b.node("ShaderNodeMath", [columns], operation="CEIL").outputs[0]
        column = b.node("ShaderNodeMath", [self.island, columns], operation="FLOORED_MODULO").outputs[0]
        rows = b.node("ShaderNodeMath", [self.island, columns], operation="DIVIDE").outputs[0]
        row = b.node("ShaderNodeMath", [rows], operation="FLOOR").outputs[0]
        self.tile = b.node("ShaderNodeVectorMath", {"Vector": b.node("ShaderNodeCombineXYZ", [column, row]).outputs[0],
                                                    "Scale": 2.0}, operation="SCALE").outputs[0]

    def in_plane(self, point):
        """``point`` turned so that the rig's plane is XY."""
        return self.b.node("FunctionNodeRotateVector", [point, self._onto_plane]).outputs[0]

    def uv(self, point, islands=False):
        """``point``'s place in the rest cage's bounding square, in the plane: the cage's UVs;
        with ``islands``, moved to its island's tile (a point of no known island: the unit
        square)."""
        b = self.b
        square = b.math("DIVIDE", b.math("SUBTRACT", self.in_plane(point), self.corner), self.span)
        return b.math("ADD", square, self.tile) if islands else square

    def mapped(self, point, about=None, in_island=False):
        """``point`` (a field on the deformed geometry) through the map of the triangle nearest
        ``about`` (by default the point itself); with ``in_island``, the nearest of the point's
        island (:attr:`island`, which must be known)."""
        b = self.b
        about = point if about is None else about
        if in_island:
            face_index = b.node("GeometryNodeFieldOnDomain", {"Value": b.node("GeometryNodeInputIndex").outputs[0]},
                                domain="FACE", data_type="INT").outputs[0]
            face = b.node("GeometryNodeSampleNearestSurface",
                          {"Mesh": self.rest, "Value": face_index, "Group ID": self.island, "Sample Position": about,
                           "Sample Group ID": self.island}, data_type="INT").outputs["Value"]
        else:
            face = b.node("GeometryNodeSampleNearest", {"Geometry": self.rest, "Sample Position": about},
                          domain="FACE").outputs[0]

        def at_face(field, data_type):
            return b.node("GeometryNodeSampleIndex", {"Geometry": self.rest, "Value": field, "Index": face},
                          data_type=data_type, domain="FACE").outputs[0]

        from_corner = b.math("SUBTRACT", point, at_face(self.face_rest_corner, "FLOAT_VECTOR"))
        turned = b.node("FunctionNodeTransformPoint", [from_corner, at_face(self.face_map, "FLOAT4X4")]).outputs[0]
        return b.math("ADD", at_face(self.face_posed_corner, "FLOAT_VECTOR"), turned)


def _rigged_selection(b, rigged_name):
    """True where the rig deforms: everywhere, or on the layers marked ``rigged_name``."""
    rigged = b.node("GeometryNodeInputNamedAttribute", {"Name": rigged_name}, data_type="BOOLEAN")
    unmarked = b.node("FunctionNodeBooleanMath", [rigged.outputs["Exists"]], operation="NOT").outputs[0]
    return b.node("FunctionNodeBooleanMath", [unmarked, rigged.outputs[0]], operation="OR").outputs[0]


def _map_bezier_handles(b, cage, geometry, selection):
    """Bezier handles set FREE, so Blender does not derive them again from the moved control
    points, and where they and their points were captured: (curve, left, right, point). Vector handles stay vector:
    Blender keeps their segments straight between the moved points.

    Set Position drags a FREE handle along with its control point, so the handles are mapped
    from where they were after the points move (:func:`_set_bezier_handles`); mapped before,
    each moved by its own map and again by its point's (a circle dragged by 0.25 strayed 0.19
    from the drag). Only their places are captured here, a copy: mapping them is a search per
    point that Set Curve Handle Positions runs on Bezier curves alone."""
    handles = b.node("GeometryNodeInputCurveHandlePositions")
    curve = geometry
    for side in ("LEFT", "RIGHT"):
        curve = b.node("GeometryNodeCurveSetHandles", {"Curve": curve, "Selection": _free(b, selection, side)},
                       handle_type="FREE", mode={side}).outputs[0]
    captured = b.node("GeometryNodeCaptureAttribute", {"Geometry": curve}, domain="POINT")
    for side, field in (("Left", handles.outputs["Left"]), ("Right", handles.outputs["Right"]), ("Point", cage.position)):
        captured.capture_items.new("VECTOR", side)
        # By name: Blender 5.2 added a Selection input before the captured items.
        b.group.links.new(field, captured.inputs[side])
    return captured.outputs[0], captured.outputs["Left"], captured.outputs["Right"], captured.outputs["Point"]


def _has_bezier_curves(b, geometry):
    """Whether ``geometry`` has a Bezier curve, or grease-pencil stroke (a boolean single value):
    its curves and strokes counted once all others are deleted (grease pencil has no statistics
    of its own)."""
    other = b.node("FunctionNodeBooleanMath", [_is_bezier(b)], operation="NOT").outputs[0]
    bezier = b.node("GeometryNodeDeleteGeometry", {"Geometry": geometry, "Selection": other}, domain="CURVE").outputs[0]
    strokes = b.node("GeometryNodeGreasePencilToCurves", {"Grease Pencil": bezier, "Layers as Instances": False})
    counts = [b.node("GeometryNodeAttributeDomainSize", {"Geometry": found}, component="CURVE").outputs["Spline Count"]
              for found in (bezier, strokes.outputs[0])]
    total = b.node("ShaderNodeMath", counts, operation="ADD").outputs[0]
    return b.node("FunctionNodeCompare", {"A": total, "B": 0.5}, data_type="FLOAT", operation="GREATER_THAN").outputs[0]


def _on_bezier_curves(b, selection):
    """``selection`` on Bezier curves alone, the only ones with handles: a poly stroke's points
    (nearly every drawing's) are not mapped twice more (review: twice the evaluation time of a
    10,720-point drawing)."""
    return b.node("FunctionNodeBooleanMath", [selection, _is_bezier(b)], operation="AND").outputs[0]


def _is_bezier(b):
    """Whether a point's or curve's curve is a Bezier curve (a field)."""
    curve_type = b.node("GeometryNodeInputNamedAttribute", {"Name": "curve_type"}, data_type="INT").outputs[0]
    return b.node("FunctionNodeCompare", {"A": curve_type, "B": CURVE_TYPE_BEZIER}, data_type="INT",
                  operation="EQUAL").outputs[0]


def _free(b, selection, side):
    """``selection`` less the points whose ``side`` ("LEFT" or "RIGHT") handle Blender derives
    from the moved points: a vector handle, and an aligned one opposite a vector handle (Blender
    lines it up with that one; mapped, it kinked the joint, QA)."""
    other = "RIGHT" if side == "LEFT" else "LEFT"
    vector = b.node("GeometryNodeCurveHandleTypeSelection", handle_type="VECTOR", mode={side}).outputs[0]
    aligned = b.node("GeometryNodeCurveHandleTypeSelection", handle_type="ALIGN", mode={side}).outputs[0]
    opposite_vector = b.node("GeometryNodeCurveHandleTypeSelection", handle_type="VECTOR", mode={other}).outputs[0]
    follows = b.node("FunctionNodeBooleanMath", [aligned, opposite_vector], operation="AND").outputs[0]
    derived = b.node("FunctionNodeBooleanMath", [vector, follows], operation="OR").outputs[0]
    return b.node("FunctionNodeBooleanMath", [selection, derived], operation="NIMPLY").outputs[0]


def _set_bezier_handles(b, cage, curve, selection, left, right, point):
    """The free Bezier handles of the moved ``curve`` mapped from where they were (``left`` and
    ``right``, captured before the points moved), both by the map of their control point's
    triangle (``point``, its place then): an affine map keeps a smooth joint's two handles in
    line, where each handle's own nearest triangle turned them apart (a kink of 7 degrees in a
    circle dragged by 0.6 of its radius)."""
    given = drawing = curve
    for side, position in (("LEFT", left), ("RIGHT", right)):
        mapped, free = cage.mapped(position, about=point), _free(b, selection, side)
        curve = b.node("GeometryNodeSetCurveHandlePositions",
                       {"Curve": curve, "Selection": free, "Position": mapped}, mode=side).outputs[0]
        # Set Curve Handle Positions leaves grease pencil alone (Blender 4.5-5.2): a drawing's
        # Bezier strokes kept their handles' rest directions, turned parts bent (QA). Their
        # handles are written as the attributes they are, on drawings alone (a mesh would get
        # attributes of those names).
        drawing = b.node("GeometryNodeStoreNamedAttribute",
                         {"Geometry": drawing, "Name": f"handle_{side.lower()}", "Value": mapped, "Selection": free},
                         data_type="FLOAT_VECTOR", domain="POINT").outputs[0]
    layers = b.node("GeometryNodeAttributeDomainSize", {"Geometry": given},
                    component="GREASEPENCIL").outputs["Layer Count"]
    has_drawings = b.node("FunctionNodeCompare", {"A": layers, "B": 0}, data_type="INT",
                          operation="GREATER_THAN").outputs[0]
    return b.node("GeometryNodeSwitch", {"Switch": has_drawings, "False": curve, "True": drawing},
                  input_type="GEOMETRY").outputs[0]


def _map_points(b, cage, geometry, selection):
    """Every point moved: inside the cage (its island's part, where it has one) by its
    displacement sampled at the point's UV (see the module docstring), or where it is the cage's
    point of its own index with no island known (a mesh that is its own graph, bound by an
    older version) by that point's; elsewhere through its nearest triangle's map (its island's).

    A cage without islands (nearly every rig) takes a branch that never reads them: a Switch
    evaluates only the branch it passes on, and the islands' lookups, run on points of no island
    too, made a 50,000-vertex mesh's evaluation a fifth to a third slower (docs/addon_speed.md).

    Returns the moved geometry and a field on it: whether each point was found on the cage (by
    its UV or its index), which a pose that folds nothing keeps it on."""
    (by_place, on_place), (by_island, on_island) = (_mapped_points(b, cage, geometry, selection, islands)
                                                    for islands in (False, True))
    moved, on_cage = (b.node("GeometryNodeSwitch", {"Switch": cage.has_islands, "False": place, "True": island},
                             input_type=kind).outputs[0]
                      for place, island, kind in ((by_place, by_island, "GEOMETRY"), (on_place, on_island, "BOOLEAN")))
    return moved, on_cage


def _mapped_points(b, cage, geometry, selection, islands):
    """:func:`_map_points`'s geometry and field, the points' islands read with ``islands`` (else
    every point is looked up by its place, or by its index where that is the cage's point)."""
    group, position = b.group, cage.position
    shift = b.math("SUBTRACT", cage.posed, position)
    uv = cage.uv(position, islands)
    displacement = b.node("GeometryNodeSampleUVSurface",
                          {"Mesh": cage.rest, "Value": shift, "UV Map": uv, "Sample UV": uv}, data_type="FLOAT_VECTOR")
    own = _OwnCagePoint(b, cage)
    own_found = own.found
    if islands:
        known = b.node("FunctionNodeCompare", {"A": cage.island, "B": 0.5}, data_type="FLOAT",
                       operation="GREATER_THAN").outputs[0]
        own_found = b.node("FunctionNodeBooleanMath", [own.found, known], operation="NIMPLY").outputs[0]
    own_shift = b.node("GeometryNodeSampleIndex", {"Geometry": cage.rest, "Value": shift, "Index": own.index},
                       data_type="FLOAT_VECTOR", domain="POINT").outputs[0]
    shifted = b.node("GeometryNodeSwitch", {"Switch": own_found, "False": displacement.outputs["Value"],
                                            "True": own_shift}, input_type="VECTOR").outputs[0]
    found = b.node("FunctionNodeBooleanMath", [own_found, displacement.outputs["Is Valid"]], operation="OR").outputs[0]
    # Captured once for every point, so the search below runs only where both lookups missed.
    captured = b.node("GeometryNodeCaptureAttribute", {"Geometry": geometry}, domain="POINT")
    captured.capture_items.new("BOOLEAN", "Inside")
    captured.capture_items.new("VECTOR", "Moved")
    # By name: Blender 5.2 added a Selection input before the captured items.
    group.links.new(found, captured.inputs["Inside"])
    group.links.new(b.math("ADD", position, shifted), captured.inputs["Moved"])
    inside, moved_inside = captured.outputs["Inside"], captured.outputs["Moved"]
    both = b.node("FunctionNodeBooleanMath", [selection, inside], operation="AND").outputs[0]
    outside = b.node("FunctionNodeBooleanMath", [selection, inside], operation="NIMPLY").outputs[0]
    moved = b.node("GeometryNodeSetPosition",
                   {"Geometry": captured.outputs[0], "Selection": both, "Position": moved_inside}).outputs[0]
    searches = [(outside, False)]
    if islands:
        # Each search at its own points alone: a Set Position evaluates its position at the
        # points it selects, but a search's structure (the nearest triangle's tree, one per
        # island for the search by island) is built whenever its node runs, points or none.
        searches = [(b.node("FunctionNodeBooleanMath", [outside, known], operation=operation).outputs[0], in_island)
                    for in_island, operation in ((False, "NIMPLY"), (True, "AND"))]
    for chosen, in_island in searches:
        moved = b.node("GeometryNodeSetPosition", {"Geometry": moved, "Selection": chosen,
                                                   "Position": cage.mapped(position, in_island=in_island)}).outputs[0]
    return moved, inside


class _OwnCagePoint:
    """Whether each point of the deformed geometry is the cage's point of the same index, at
    its rest place in the plane (to 1e-5 of the cage's extent): so it is where a mesh is its own
    graph, unless edited since binding. Where islands of such a mesh overlap in the plane (a
    puppet's arm over its body), the UV lookup cannot tell which island a point belongs to (it
    moved body points with the arm); the index can, where the points have no island of their
    own (a rig bound by an older version). Fields ``index`` and ``found``."""

    def __init__(self, b, cage):
        self.index = b.node("GeometryNodeInputIndex").outputs[0]
        rest = b.node("GeometryNodeSampleIndex", {"Geometry": cage.rest, "Value": cage.position, "Index": self.index},
                      data_type="FLOAT_VECTOR", domain="POINT").outputs[0]
        apart = b.math("SUBTRACT", cage.position, rest)
        across = b.node("ShaderNodeVectorMath", [apart, cage.normal], operation="DOT_PRODUCT").outputs["Value"]
        along = b.math("SUBTRACT", apart, b.node("ShaderNodeVectorMath", {0: cage.normal, "Scale": across},
                                                 operation="SCALE").outputs[0])
        distance = b.node("ShaderNodeVectorMath", [along], operation="LENGTH").outputs["Value"]
        extent = b.node("ShaderNodeVectorMath", [cage.span], operation="LENGTH").outputs["Value"]
        tolerance = b.node("ShaderNodeMath", [extent, 1e-5], operation="MULTIPLY").outputs[0]
        near = b.node("FunctionNodeCompare", {"A": distance, "B": tolerance},
                      data_type="FLOAT", operation="LESS_THAN").outputs[0]
        count = b.node("GeometryNodeAttributeDomainSize", {"Geometry": cage.rest}, component="MESH")
        listed = b.node("FunctionNodeCompare", {"A": self.index, "B": count.outputs["Point Count"]},
                        data_type="INT", operation="LESS_THAN").outputs[0]
        self.found = b.node("FunctionNodeBooleanMath", [near, listed], operation="AND").outputs[0]


def _stroke_order(b, cage, moved, enabled, selection, on_cage):
    """With ``enabled`` and grease pencil in ``moved``: strokes over a fold drawn last, under one
    first, on the layers the rig deforms (``selection``; the others keep their order: lying at
    rest under a lifted cage, they would all count as under a fold).

    Grease pencil draws strokes in their order within a layer. Where the pose folds the shape
    over itself, the strokes lying on the folded-over part must draw after the ones under it;
    everywhere else the drawing's own order stands (a face's fill under its eyes, say, even
    where the face moved further than the eyes). A ray from behind along the plane's normal
    through the posed cage finds the lowest layer at each point, one from the front the
    highest: the point lies over a fold when it is higher than the lowest, under one when it
    is lower than the highest. A stroke most of whose points lie over a fold sorts after the
    others, one most of whose points lie under a fold before them (an arm an overlap pin puts
    behind a body drawn as one large stroke), each group keeping its order
    (:func:`_sorted_drawings`). A stroke the fold laid partly over itself (a head's fill with its ears) cannot be
    split, and stays where most of it lies.
    """
    position, normal = cage.position, cage.normal
    cage_size = b.node("ShaderNodeVectorMath", [cage.span], operation="LENGTH").outputs["Value"]  # in its plane
    posed_cage = b.node("GeometryNodeSetPosition", {"Geometry": cage.rest, "Position": cage.posed}).outputs[0]
    height = b.node("ShaderNodeVectorMath", [position, normal], operation="DOT_PRODUCT").outputs["Value"]
    below = b.node("ShaderNodeVectorMath", {"Vector": normal, "Scale": b.node(
        "ShaderNodeMath", [cage_size, -2.0], operation="MULTIPLY").outputs[0]}, operation="SCALE").outputs[0]
    reach = b.node("ShaderNodeMath", [cage_size, 4.0], operation="MULTIPLY").outputs[0]
    ray = b.node("GeometryNodeRaycast", {"Target Geometry": posed_cage, "Source Position": b.math("ADD", position, below),
                                         "Ray Direction": normal, "Ray Length": reach})
    lowest = b.node("ShaderNodeVectorMath", [ray.outputs["Hit Position"], normal],
                    operation="DOT_PRODUCT").outputs["Value"]
    # A ten-thousandth of the cage's size: far above rounding where the point and the layer
    # under it are the same, below the lift between the layers of any fold whose top moved a
    # hundredth of the size more than its bottom, in drags up to about the shape's size (beyond,
    # the automatic lift eases off and a larger difference is needed: solver/rigging/depth.py).
    margin = b.node("ShaderNodeMath", [cage_size, 1e-4], operation="MULTIPLY").outputs[0]
    above = b.node("ShaderNodeMath", [height, lowest], operation="SUBTRACT").outputs[0]
    higher = b.node("FunctionNodeCompare", {"A": above, "B": margin}, data_type="FLOAT",
                    operation="GREATER_THAN").outputs[0]
    over_fold = b.node("FunctionNodeBooleanMath", [ray.outputs["Is Hit"], higher], operation="AND").outputs[0]
    over_fold = b.node("FunctionNodeBooleanMath", [over_fold, selection], operation="AND").outputs[0]
    down = b.node("ShaderNodeVectorMath", {"Vector": normal, "Scale": -1.0}, operation="SCALE").outputs[0]
    from_front = b.node("GeometryNodeRaycast", {"Target Geometry": posed_cage,
                                                "Source Position": b.math("SUBTRACT", position, below),
                                                "Ray Direction": down, "Ray Length": reach})
    highest = b.node("ShaderNodeVectorMath", [from_front.outputs["Hit Position"], normal],
                     operation="DOT_PRODUCT").outputs["Value"]
    beneath = b.node("ShaderNodeMath", [highest, height], operation="SUBTRACT").outputs[0]
    lower = b.node("FunctionNodeCompare", {"A": beneath, "B": margin}, data_type="FLOAT",
                   operation="GREATER_THAN").outputs[0]
    # Only a part sent behind its plane (an overlap pin below 0; the automatic order lifts, it
    # never lowers) goes under: an eye or a hole drawn on the body, covered by an arm folded
    # over it, stays on the body (drawn before it, the body covered it whole).
    rest_point = b.node("GeometryNodeSampleIndex", {"Geometry": cage.rest, "Value": position, "Index": 0},
                        data_type="FLOAT_VECTOR", domain="POINT").outputs[0]
    plane = b.node("ShaderNodeVectorMath", [rest_point, normal], operation="DOT_PRODUCT").outputs["Value"]
    sunk = b.node("ShaderNodeMath", [plane, height], operation="SUBTRACT").outputs[0]
    behind = b.node("FunctionNodeCompare", {"A": sunk, "B": margin}, data_type="FLOAT",
                    operation="GREATER_THAN").outputs[0]
    under_fold = b.node("FunctionNodeBooleanMath", [from_front.outputs["Is Hit"], lower], operation="AND").outputs[0]
    under_fold = b.node("FunctionNodeBooleanMath", [under_fold, behind], operation="AND").outputs[0]
    under_fold = b.node("FunctionNodeBooleanMath", [under_fold, selection], operation="AND").outputs[0]
    # The rays are most of the order's cost (0.8 ms of a still 1,216-point monkey's 2.2 ms a
    # frame). Where the posed cage lies in its plane (nothing folded, or pinned off it), the
    # layer under and over every point the map found on the cage (``on_cage``; a ray from
    # one off it misses) is the plane: its height tells alone.
    off_plane = b.node("ShaderNodeMath", [sunk], operation="ABSOLUTE").outputs[0]
    cage_lift = b.node("GeometryNodeAttributeStatistic", {"Geometry": posed_cage, "Attribute": off_plane},
                       data_type="FLOAT", domain="POINT").outputs["Max"]
    flat = b.node("FunctionNodeCompare", {"A": cage_lift, "B": margin}, data_type="FLOAT",
                  operation="LESS_EQUAL").outputs[0]
    lifted = b.node("FunctionNodeCompare", {"A": sunk, "B": b.node("ShaderNodeMath", [margin, -1.0],
                                                                     operation="MULTIPLY").outputs[0]},
                    data_type="FLOAT", operation="LESS_THAN").outputs[0]
    rigged_on_cage = b.node("FunctionNodeBooleanMath", [selection, on_cage], operation="AND").outputs[0]
    over_plane = b.node("FunctionNodeBooleanMath", [lifted, rigged_on_cage], operation="AND").outputs[0]
    under_plane = b.node("FunctionNodeBooleanMath", [behind, rigged_on_cage], operation="AND").outputs[0]
    weights = [b.node("ShaderNodeMath", [_stroke_share(b, over), _stroke_share(b, under)], operation="SUBTRACT").outputs[0]
               for over, under in ((over_fold, under_fold), (over_plane, under_plane))]
    # A Switch given one value evaluates only the field it passes on: no ray is cast then.
    sort_weight = b.node("GeometryNodeSwitch", {"Switch": flat, "False": weights[0], "True": weights[1]},
                         input_type="FLOAT").outputs[0]
    parts = b.node("GeometryNodeSeparateComponents", [moved])
    # Weighed on the drawings, where the layers' marks of what is rigged are read (the curves
    # they are sorted as know nothing of layers).
    weighed = b.node("GeometryNodeCaptureAttribute", {"Geometry": parts.outputs["Grease Pencil"]}, domain="CURVE")
    weighed.capture_items.new("FLOAT", "Weight")
    b.group.links.new(sort_weight, weighed.inputs["Weight"])
    drawings = _sorted_drawings(b, weighed.outputs[0], weighed.outputs["Weight"])
    joined = b.node("GeometryNodeJoinGeometry")
    for name in ("Mesh", "Curve", "Point Cloud", "Volume", "Instances"):
        b.group.links.new(parts.outputs[name], joined.inputs[0])
    b.group.links.new(drawings, joined.inputs[0])
    has_drawings = b.node("GeometryNodeAttributeDomainSize", {"Geometry": parts.outputs["Grease Pencil"]},
                          component="GREASEPENCIL").outputs["Layer Count"]
    reorder = b.node("FunctionNodeBooleanMath", [enabled, b.node(
        "FunctionNodeCompare", {"A": has_drawings, "B": 0}, data_type="INT", operation="GREATER_THAN").outputs[0]],
        operation="AND").outputs[0]
    return b.node("GeometryNodeSwitch", {"Switch": reorder, "False": moved, "True": joined.outputs[0]},
                  input_type="GEOMETRY").outputs[0]


def _stroke_share(b, point_test):
    """Whether more than half of each stroke's points pass ``point_test``: evaluated at each
    point as a number, then averaged over the stroke (on the curve domain alone the test would
    run once, at the stroke's mean position; as a boolean, the points would be combined as
    booleans, not counted)."""
    each = b.node("GeometryNodeFieldOnDomain", {"Value": point_test}, domain="POINT", data_type="FLOAT").outputs[0]
    mean = b.node("GeometryNodeFieldOnDomain", {"Value": each}, domain="CURVE", data_type="FLOAT").outputs[0]
    return b.node("FunctionNodeCompare", {"A": mean, "B": 0.5}, data_type="FLOAT",
                  operation="GREATER_THAN").outputs[0]


def _sorted_drawings(b, drawings, sort_weight):
    """``drawings`` with each layer's strokes weighed -1 (under a fold) drawn first and +1
    (over one) last, the others between in their order; unchanged while no stroke is either.

    Sort Elements does not sort grease-pencil strokes (Blender 4.5-5.2), and passing them
    through curves and back makes new layers without the originals' lighting, blend modes,
    view-layer filters or parents. Delete Geometry and Join keep a layer's settings, so each
    layer is drawn as three layers of its name and settings (its strokes under a fold, the
    rest, those over one), a repeat over the layers keeping each layer's three together in the
    layer order. Joined layers lose their groups and keep the current drawing alone (keyed at
    frame 0), which is why this waits for a stroke to move.
    """
    count = b.node("GeometryNodeAttributeDomainSize", {"Geometry": drawings},
                   component="GREASEPENCIL").outputs["Layer Count"]
    start = b.node("GeometryNodeRepeatInput", {"Iterations": count})
    end = b.node("GeometryNodeRepeatOutput")
    start.pair_with_output(end)
    layer = b.node("GeometryNodeInputIndex").outputs[0]
    other_layers = b.node("FunctionNodeCompare", {"A": layer, "B": start.outputs["Iteration"]},
                          data_type="INT", operation="NOT_EQUAL").outputs[0]
    # Join puts the input linked last first: link the last layer to draw first.
    layered = b.node("GeometryNodeJoinGeometry")
    for low, high in ((0.5, 2.0), (-0.5, 0.5), (-2.0, -0.5)):
        outside = b.node("FunctionNodeCompare", {"A": sort_weight, "B": (low + high) / 2, "Epsilon": (high - low) / 2},
                         data_type="FLOAT", operation="NOT_EQUAL").outputs[0]
        part = b.node("GeometryNodeDeleteGeometry", {"Geometry": drawings, "Selection": outside}, domain="CURVE")
        piece = b.node("GeometryNodeDeleteGeometry", {"Geometry": part.outputs[0], "Selection": other_layers},
                       domain="LAYER")
        b.group.links.new(piece.outputs[0], layered.inputs[0])
    b.group.links.new(start.outputs["Geometry"], layered.inputs[0])
    b.group.links.new(layered.outputs[0], end.inputs["Geometry"])
    return b.node("GeometryNodeSwitch", {"Switch": _any_moved(b, drawings, sort_weight), "False": drawings,
                                         "True": end.outputs["Geometry"]}, input_type="GEOMETRY").outputs[0]


def _any_moved(b, drawings, sort_weight):
    """Whether any stroke of ``drawings`` weighs other than 0 (a boolean single value): the
    drawings' strokes are counted as curves, grease pencil having no stroke count of its own."""
    level = b.node("FunctionNodeCompare", {"A": sort_weight, "B": 0.0, "Epsilon": 0.5},
                   data_type="FLOAT", operation="EQUAL").outputs[0]
    moving = b.node("GeometryNodeDeleteGeometry", {"Geometry": drawings, "Selection": level}, domain="CURVE")
    as_curves = b.node("GeometryNodeGreasePencilToCurves", {"Grease Pencil": moving.outputs[0],
                                                             "Layers as Instances": False}).outputs[0]
    strokes = b.node("GeometryNodeAttributeDomainSize", {"Geometry": as_curves}, component="CURVE")
    return b.node("FunctionNodeCompare", {"A": strokes.outputs["Spline Count"], "B": 0},
                  data_type="INT", operation="GREATER_THAN").outputs[0]
