# SPDX-License-Identifier: GPL-3.0-or-later
"""Where users find the operators and what Blender's interface asks of them: menu entries,
polls that say why an operator does not apply, properties that are not remembered or keyed
where that would surprise, the mode an operator leaves the object in."""

from types import SimpleNamespace

import bpy
import pytest
from mathutils import Matrix

import rig_checks as checks
from test_rig_mesh import grid, rig_with_two_handles

OPERATORS = ("bind", "unbind", "add_handle", "remove_handle", "make_handles_editable", "drag", "bake", "clear_bake")


class MenuLayout:
    """Stands in for a menu's layout headless: records the menus and operators drawn."""

    def __init__(self):
        self.items = []

    def operator(self, idname, **_):
        self.items.append(idname)
        return SimpleNamespace()

    def menu(self, idname, **_):
        self.items.append(idname)

    def separator(self, **_):
        pass


def drawn_by(menu_name):
    """What the draw functions the extension appended to Blender's ``menu_name`` draw."""
    menu = getattr(bpy.types, menu_name)
    ours = [f for f in menu._dyn_ui_initialize() if f.__module__.endswith(".menus")]
    layout = MenuLayout()
    for draw in ours:
        draw(SimpleNamespace(layout=layout), bpy.context)
    return layout.items


def test_every_operator_is_in_the_object_menu_and_the_bake_under_animation(addon):
    assert drawn_by("VIEW3D_MT_object") == ["SHAPEDEFORM_MT_object"]
    layout = MenuLayout()
    bpy.types.SHAPEDEFORM_MT_object.draw(SimpleNamespace(layout=layout), bpy.context)
    assert sorted(set(layout.items)) == sorted(f"shapedeform.{name}" for name in OPERATORS)
    for idname in layout.items:  # each one registered
        getattr(bpy.ops.shapedeform, idname.split(".")[1]).get_rna_type()
    assert drawn_by("VIEW3D_MT_object_animation") == ["shapedeform.bake"]
    for edit_menu in ("VIEW3D_MT_edit_mesh", "VIEW3D_MT_edit_curve", "VIEW3D_MT_edit_greasepencil"):
        assert drawn_by(edit_menu) == ["shapedeform.add_handle"]


@pytest.mark.parametrize("name, message", [
    ("add_handle", "Bind the object before adding handles"),
    ("remove_handle", "Select a rig or the handles to remove"),
    ("unbind", "not bound"),
    ("drag", "Select a bound object"),
    ("bake", "Select bound objects to bake"),
    ("clear_bake", "Select bound objects to clear"),
])
def test_operators_that_need_a_rig_say_so_in_their_poll(addon, name, message):
    """Greyed out in menus and panels with the reason as tooltip; a script's call names it."""
    grid()
    operator = getattr(bpy.ops.shapedeform, name)
    assert not operator.poll()
    with pytest.raises(RuntimeError, match=message):
        operator()
    assert bpy.ops.shapedeform.bind.poll()


def test_bind_is_greyed_out_for_what_it_cannot_rig(addon):
    bpy.ops.object.light_add(type="POINT")
    assert not bpy.ops.shapedeform.bind.poll()
    with pytest.raises(RuntimeError, match="light object: Shape Deform rigs meshes"):
        bpy.ops.shapedeform.bind()
    bpy.ops.object.empty_add(type="IMAGE")  # a reference image: says how to make one it can rig
    with pytest.raises(RuntimeError, match=r"image empty .*\(Add > Image > Mesh Plane\) and bind that"):
        bpy.ops.shapedeform.bind()
    bpy.ops.object.text_add()
    bpy.context.object.data.body = "   "  # says why a text of spaces cannot be rigged
    with pytest.raises(RuntimeError, match="shows no glyphs: type some text"):
        bpy.ops.shapedeform.bind()
    obj, _, _ = rig_with_two_handles()
    bpy.context.view_layer.objects.active = obj
    with pytest.raises(RuntimeError, match="already bound"):
        bpy.ops.shapedeform.bind()


@pytest.mark.parametrize("name, properties", [
    ("add_handle", ("kind", "location")), ("remove_handle", ("handle",)), ("bake", ("frame_start", "frame_end"))])
def test_buttons_and_menus_do_not_reuse_the_last_calls_choices(addon, name, properties):
    """Blender's interface starts an operator with its last call's properties unless they skip
    saving: the panel's "+" after its overlap-pin button would add another pin, a bake would keep
    the last shot's frame range. (A script's call never reuses them, so only the flag shows it.)"""
    rna = getattr(bpy.ops.shapedeform, name).get_rna_type()
    for prop in properties:
        assert rna.properties[prop].is_skip_save, prop


def test_the_lists_remove_button_removes_its_active_handle_not_the_selection(addon):
    obj, left, right = rig_with_two_handles()
    obj.shapedeform.active_handle = 0  # the list's active item: the left handle
    checks.select_only(right)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.remove_handle(handle=left.name) == {"FINISHED"}
    assert [h.object for h in obj.shapedeform.handles] == [right]
    for name in ("Nope", obj.shapedeform.cage.name):
        with pytest.raises(RuntimeError, match=f"'{name}' is not a handle"):
            bpy.ops.shapedeform.remove_handle(handle=name)


def test_picking_a_handle_in_the_list_selects_its_empty_in_object_mode_only(addon):
    obj, left, right = rig_with_two_handles()
    view_layer = bpy.context.view_layer
    checks.select_only(obj)
    view_layer.objects.active = obj
    obj.shapedeform.active_handle = 0  # a click in the list
    assert view_layer.objects.active == left and left.select_get() and not obj.select_get()
    obj.shapedeform.active_handle = 1  # the list stays: the Empty belongs to the same rig
    assert view_layer.objects.active == right and right.select_get() and not left.select_get()

    view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    obj.shapedeform.active_handle = 0
    assert view_layer.objects.active == obj and obj.mode == "EDIT"
    bpy.ops.mesh.select_all(action="DESELECT")
    bpy.ops.object.mode_set(mode="OBJECT")
    obj.data.vertices[0].select = True
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}  # its own index change selects nothing
    assert view_layer.objects.active == obj and obj.mode == "EDIT" and obj.shapedeform.active_handle == 2


def test_rig_state_offers_no_keyframes_but_the_energy_and_pins_do(addon):
    properties = bpy.types.Object.bl_rna.properties["shapedeform"].fixed_type.properties
    for name in ("is_bound", "kind", "active_handle", "pin_kind", "graph_mode", "density", "region_size",
                 "layers", "show_overlay", "status"):
        assert not properties[name].is_animatable, name
    for name in ("weight_laplacian", "weight_mvc", "weight_edge", "preserve_area", "prevent_flips",
                 "iterations", "render_iterations", "in_front", "stiffness", "extent"):
        assert properties[name].is_animatable, name


def test_bind_and_unbind_leave_the_object_in_the_mode_they_found_it_in(addon):
    obj = grid()
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert obj.mode == "EDIT" and obj.shapedeform.is_bound
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert obj.mode == "EDIT" and not obj.shapedeform.is_bound

    flat = grid("Flat")
    flat.data.transform(Matrix.Diagonal((1.0, 0.0, 1.0, 1.0)))  # no area: cannot be rigged
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError):
        bpy.ops.shapedeform.bind()
    assert flat.mode == "EDIT" and not flat.shapedeform.is_bound


def test_the_status_bar_message_of_a_failed_update_goes_once_updates_work(addon):
    handlers = addon.shapedeform_addon.handlers
    if getattr(bpy.context, "workspace", None) is None:
        pytest.skip("no workspace to show a status bar message")
    obj, left, _ = rig_with_two_handles()
    other, _, other_right = rig_with_two_handles()
    y = left.location.y
    left.location.y = float("nan")  # a driver gone wrong: the update fails, the pose stays
    bpy.context.view_layer.update()
    assert obj.shapedeform.status and obj.name in handlers._status_text
    other_right.location.y += 0.1  # another rig works: the failure still shows
    bpy.context.view_layer.update()
    assert not other.shapedeform.status and obj.name in handlers._status_text
    left.location.y = y + 0.1
    bpy.context.view_layer.update()
    assert not obj.shapedeform.status and handlers._status_text == ""


def test_deleting_a_handles_empty_removes_the_handle(addon):
    """As the README says beside the list's "-": X in the viewport works too."""
    obj, left, right = rig_with_two_handles()
    middle = checks.add_handle(obj, checks.world(obj, [0.0, 0.0, 0.0]))
    checks.select_only(middle)
    assert bpy.ops.object.delete() == {"FINISHED"}
    right.location.y += 0.3
    bpy.context.view_layer.update()
    assert obj.shapedeform.status == ""
    present = addon.shapedeform_addon.rig_format.present
    assert [h.object for h in obj.shapedeform.handles if present(h.object)] == [left, right]
    assert len(addon.shapedeform_addon.rig.get(obj).handle_objects) == 2
    # The list shows the entry as deleted; its "-" removes it.
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.remove_handle(handle=middle.name) == {"FINISHED"}
    assert [h.object for h in obj.shapedeform.handles] == [left, right]


def test_add_handle_in_draw_mode_keeps_the_mode_and_the_active_object(addon):
    """From grease pencil's Draw Mode (or Sculpt Mode) the handle goes to the 3D cursor and the
    drawing stays active in its mode (the new Empty was made active, the drawing left stranded)."""
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    monkey = bpy.context.active_object
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    bpy.ops.object.mode_set(mode="PAINT_GREASE_PENCIL")
    bpy.context.scene.cursor.location = (0.0, 0.0, 0.0)
    assert bpy.ops.shapedeform.add_handle() == {"FINISHED"}
    assert len(monkey.shapedeform.handles) == 1
    assert bpy.context.active_object == monkey and monkey.mode == "PAINT_GREASE_PENCIL"


def test_a_hidden_object_in_edit_mode_is_unbound_without_a_traceback(addon):
    """Blender lets a hidden object leave Edit Mode but not enter it again: Unbind works and
    leaves it in Object Mode (it raised from going back, the rig already removed)."""
    obj, _, _ = rig_with_two_handles()
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    obj.hide_viewport = True
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not obj.shapedeform.is_bound and obj.mode == "OBJECT"


def test_a_handle_added_off_the_shape_says_it_holds_the_nearest_part_at_a_distance(addon, capsys):
    """The 3D cursor left far from the shape: the handle is added there (a lever on the nearest
    part, as before) and the status bar says so; one on the shape says nothing."""
    obj, _, _ = rig_with_two_handles()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 3.0, 0.0])) == {"FINISHED"}
    assert "of the shape's size off it: it holds the nearest part at a distance" in capsys.readouterr().out
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.0, 0.0, 0.0])) == {"FINISHED"}
    assert "off it" not in capsys.readouterr().out

    # On a face far from every vertex (Blender's Plane, its own graph of four points) is on it
    # (off its centre, where all four corners are equally near and the region would take them).
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(5.0, 0.0, 0.0))
    plane = bpy.context.active_object
    plane.shapedeform.graph_mode = "OWN"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert len(addon.shapedeform_addon.rig.get(plane).graph.points) == 4
    for place in ([5.2, 0.1, 0.0], [4.1, -0.9, 0.0]):
        bpy.context.view_layer.objects.active = plane
        assert bpy.ops.shapedeform.add_handle(location=place) == {"FINISHED"}
        assert "off it" not in capsys.readouterr().out


def test_bind_refuses_an_object_linked_without_an_override(addon, tmp_path):
    """A linked object (no library override): Bind was offered and made a cage, a collection
    and a node group, and wrote into the linked object, all lost on saving; it is greyed out
    and refused by name, as every other operator on such a rig is."""
    from test_rig_mesh import grid

    grid("Plain")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "lib.blend"))
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    with bpy.data.libraries.load(str(tmp_path / "lib.blend"), link=True) as (_, linked):
        linked.objects = ["Plain"]
    bpy.context.scene.collection.objects.link(linked.objects[0])
    plain = bpy.data.objects["Plain"]
    bpy.context.view_layer.objects.active = plain
    before = checks.snapshot()
    assert not bpy.ops.shapedeform.bind.poll()
    with pytest.raises(RuntimeError, match="comes from the library 'lib.blend' without a library override"):
        bpy.ops.shapedeform.bind()
    assert checks.snapshot() == before and not plain.shapedeform.is_bound


def test_a_solver_refusal_names_the_setting_as_the_sidebar_does(addon):
    """Preserve Area with every outline point held by a handle: the message named the solver's
    parameter, preserve_area."""
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    plane.shapedeform.graph_mode = "OWN"
    plane.shapedeform.preserve_area = True
    with pytest.raises(RuntimeError) as raised:
        checks.bind_with_handles(plane, [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0])
    assert "preserve_area" not in str(raised.value) and "Preserve Area" in str(raised.value)


def test_every_property_of_the_extension_has_a_name_and_a_description(addon):
    """Python tooltips, the override view and driver paths show them (the rig's top-level
    property was called "shapedeform", and three of its properties had no description)."""
    pointer = bpy.types.Object.bl_rna.properties["shapedeform"]
    missing = [] if pointer.description and pointer.name != "shapedeform" else ["Object.shapedeform"]
    groups, seen = [pointer.fixed_type], set()
    while groups:
        group = groups.pop()
        if group.identifier in seen:
            continue
        seen.add(group.identifier)
        for prop in group.properties:
            if prop.identifier == "rna_type":
                continue
            if not prop.description:
                missing.append(f"{group.identifier}.{prop.identifier}")
            if prop.type in {"POINTER", "COLLECTION"} and prop.fixed_type.identifier.startswith("SHAPEDEFORM"):
                groups.append(prop.fixed_type)
    assert not missing, missing


def test_a_rig_whose_cage_was_deleted_says_so_the_same_way(addon):
    """The cage deleted by hand: Bind's tooltip said only "already bound", while Add Handle
    said the cage was lost; both say what happened and what to do."""
    obj, _, _ = rig_with_two_handles()
    bpy.data.objects.remove(obj.shapedeform.cage)
    bpy.context.view_layer.objects.active = obj
    for operator in (bpy.ops.shapedeform.bind, bpy.ops.shapedeform.add_handle):
        with pytest.raises(RuntimeError, match="lost its cage \\(deleted by hand.*\\): unbind it and bind it again"):
            operator()
