# SPDX-License-Identifier: GPL-3.0-or-later
"""The sidebar panel is registered in its tab and the overlay's drawing data is right."""

from types import SimpleNamespace

import bpy
import numpy as np

import rig_checks as checks
from test_rig_mesh import grid


def test_panel_is_in_its_own_tab(addon):
    for name in PANELS:
        panel = getattr(bpy.types, name)
        assert (panel.bl_space_type, panel.bl_region_type, panel.bl_category) == ("VIEW_3D", "UI", "Shape Deform")
        assert name == PANELS[0] or panel.bl_parent_id == PANELS[0]


def test_the_panel_names_the_drag_key_the_key_map_binds(addon):
    keymaps = addon.shapedeform_addon.keymaps
    assert keymaps.shortcut("shapedeform.drag") == "Ctrl Shift D"
    assert keymaps.shortcut("shapedeform.bind") == ""


def test_overlay_draws_the_posed_graph_and_regions(addon):
    overlay = addon.shapedeform_addon.overlay
    obj = grid()
    bpy.ops.shapedeform.bind()
    assert overlay.drawing_data(obj) is None  # only when asked
    obj.shapedeform.show_overlay = True
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    handle = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    handle.location.y += 0.25
    bpy.context.view_layer.update()
    data = overlay.drawing_data(obj)
    rig = addon.shapedeform_addon.rig.get(obj)
    assert data["edges"].shape == (2 * len(rig.graph.edges), 3) and data["edges"].dtype == np.float32
    assert len(data["regions"]) == len(rig.indices)
    world = checks.evaluated_mesh_points(obj) + np.array(obj.location)
    # The mesh is its own graph here: the overlay's points are the evaluated vertices.
    assert np.abs(data["edges"] - world[rig.graph.edges.ravel()]).max() < 1e-5


class RecordingLayout:
    """Stands in for a UI layout headless: records the operators and properties drawn, and
    apart from them the labels' texts."""

    def __init__(self, record=None, labels=None, buttons=None):
        self.record = [] if record is None else record
        self.labels = [] if labels is None else labels
        self.buttons = [] if buttons is None else buttons  # (idname, the properties it was given)

    def operator(self, idname, **_):
        self.record.append(idname)
        self.buttons.append((idname, SimpleNamespace()))
        return self.buttons[-1][1]  # takes operator properties

    def prop(self, _data, name, **_):
        self.record.append(name)

    def label(self, text="", **_):
        self.labels.append(text)

    def template_list(self, *args, **_):
        pass

    def column(self, **_):
        return RecordingLayout(self.record, self.labels, self.buttons)

    row = column


PANELS = ("SHAPEDEFORM_PT_panel", "SHAPEDEFORM_PT_solver", "SHAPEDEFORM_PT_animation")


def drawn(context, labels=False):
    """The operators and properties the panel and the sub-panels it shows draw (with
    ``labels``, the labels' texts)."""
    layout = RecordingLayout()
    for name in PANELS:
        panel = getattr(bpy.types, name)
        if not hasattr(panel, "poll") or panel.poll(context):
            panel.draw(SimpleNamespace(layout=layout), context)
    return layout.labels if labels else layout.record


def test_panel_offers_bind_then_handles_weights_and_bake_then_bake_again_and_clear_bake(addon):
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert drawn(bpy.context)[-1] == "shapedeform.bind"
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    handle = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    bpy.context.view_layer.objects.active = obj
    items = drawn(bpy.context)
    for expected in ("shapedeform.unbind", "shapedeform.add_handle", "weight_mvc", "preserve_area",
                     "shapedeform.bake"):
        assert expected in items
    handle.keyframe_insert("location", frame=1)
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 2) == [obj]
    items = drawn(bpy.context)
    assert "shapedeform.clear_bake" in items and "shapedeform.bake" in items  # Bake Again
    # The scene's range grown after baking: the frames left out are told (they hold a pose).
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 2
    labels = drawn(bpy.context, labels=True)
    assert "Baked frames 1 to 2: the keyframes play, the rig waits" in labels
    assert not any("hold the nearest baked pose" in label for label in labels)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 0, 40
    assert "The scene's frame 0 and frames 3 to 40 hold the nearest baked pose" in drawn(bpy.context, labels=True)
    # Its keys retimed in the Graph Editor (moved 5 frames later), the bake plays on 6-7.
    animation = obj.shapedeform.cage.data.shape_keys.animation_data
    curve = addon.shapedeform_addon.compat.channelbag(animation.action, animation.action_slot).fcurves[0]
    for point in curve.keyframe_points:
        point.co.x += 5
    assert "The scene's frames 0 to 5 and frames 8 to 40 hold the nearest baked pose" in drawn(bpy.context, labels=True)


def test_pins_show_their_kind_and_values_and_the_overlay_tints_their_reach(addon):
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [0.8, 0.0, 0.0]), kind="OVERLAP") == {"FINISHED"}
    pin = obj.shapedeform.handles[-1].object
    bpy.context.view_layer.objects.active = obj
    items = drawn(bpy.context)
    assert "in_front" in items and "extent" in items  # the active pin's values
    obj.shapedeform.active_handle = 0
    assert "in_front" not in drawn(bpy.context)  # a position handle has none

    overlay = addon.shapedeform_addon.overlay
    obj.shapedeform.show_overlay = True
    data = overlay.drawing_data(obj)
    assert len(data["reach"]) > 0 and np.all(data["reach_colors"][:, :3] == 1.0)  # in front: light
    assert data["reach_colors"][:, 3].max() == np.float32(overlay.REACH_OPACITY)
    near = np.linalg.norm(data["reach"][:, :2] - np.array(checks.world(obj, [0.8, 0.0, 0.0]))[:2], axis=1)
    assert near.max() < 1.05 * pin.shapedeform.extent * addon.shapedeform_addon.rig.get(obj).graph.size
    pin.shapedeform.in_front = -0.5
    data = overlay.drawing_data(obj)
    assert np.all(data["reach_colors"][:, :3] == 0.0)  # behind: dark
    assert data["reach_colors"][:, 3].max() == np.float32(0.5 * overlay.REACH_OPACITY)


def test_the_list_follows_a_handle_or_pin_made_active_in_the_viewport(addon):
    """A click in the viewport makes a pin or handle the active object: the list's active item
    follows it, as Blender's lists follow the active bone or material slot, so the sidebar shows
    its values and '-' removes it (they were the last added pin's); nothing else is selected."""
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handle = checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    pins = []
    for x, kind in ((0.8, "OVERLAP"), (0.0, "STARCH")):
        bpy.context.view_layer.objects.active = obj
        assert bpy.ops.shapedeform.add_handle(location=checks.world(obj, [x, 0.0, 0.0]), kind=kind) == {"FINISHED"}
        pins.append(obj.shapedeform.handles[-1].object)
    overlap, starch = pins
    settings = obj.shapedeform
    for clicked, index, values in ((overlap, 1, "in_front"), (handle, 0, None), (starch, 2, "stiffness")):
        checks.select_only(clicked)
        bpy.context.view_layer.update()  # as Blender evaluates after a click, before it redraws
        assert settings.active_handle == index, f"'{clicked.name}' clicked, item {settings.active_handle} active"
        items, labels = drawn(bpy.context), drawn(bpy.context, labels=True)
        assert values is None or (values in items and any(clicked.name in text for text in labels)), labels
        assert list(bpy.context.selected_objects) == [clicked]


def test_panel_shows_the_modifier_option_for_the_kind_of_object(addon):
    """Grease pencil: Stroke Order; a mesh, a curve, a text: Refine (both inputs of the Shape
    Deform modifier)."""
    shapedeform = addon.shapedeform_addon
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    monkey = bpy.context.active_object
    bpy.ops.object.text_add()
    text = bpy.context.active_object
    bpy.ops.curve.primitive_bezier_circle_add(location=(5.0, 0.0, 0.0))
    curve = bpy.context.active_object
    mesh = grid()
    for obj, name in ((monkey, "Stroke Order"), (mesh, "Refine"), (text, "Refine"), (curve, "Refine")):
        bpy.context.view_layer.objects.active = obj
        assert bpy.ops.shapedeform.bind() == {"FINISHED"}
        modifier = shapedeform.rig_format.modifiers_of(obj)[0]
        identifier = shapedeform.nodes.input_identifiers(modifier.node_group)[name]
        assert shapedeform.compat.modifier_input_property(modifier, identifier)[1] in drawn(bpy.context)
    # A Build modifier after the rig's: Stroke Order would drop its timing while a pose folds.
    bpy.context.view_layer.objects.active = monkey
    monkey.modifiers.new("Build", "GREASE_PENCIL_BUILD")
    modifier = shapedeform.rig_format.modifiers_of(monkey)[0]
    order = shapedeform.nodes.input_identifiers(modifier.node_group)["Stroke Order"]
    assert shapedeform.compat.modifier_input(modifier, order) is True  # bound before the Build
    assert "Drops the keyframe timing read by 'Build' while a pose folds" in drawn(bpy.context, labels=True)
    shapedeform.compat.set_modifier_input(modifier, order, False)
    assert "Would drop the keyframe timing read by 'Build' while a pose folds" in drawn(bpy.context, labels=True)


def test_a_handle_left_by_a_deleted_object_offers_unbind_and_says_why(addon):
    """Deleting a rigged object leaves its handles, as deleting a parent leaves its children;
    the sidebar on one of them says the object is gone and Unbind removes the rest of its rig."""
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    handle = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    name = obj.name
    for o in bpy.context.selected_objects:
        o.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.object.delete() == {"FINISHED"}
    bpy.context.view_layer.objects.active = handle
    assert any("not in this scene" in text for text in drawn(bpy.context, labels=True))
    assert "shapedeform.unbind" in drawn(bpy.context)
    assert bpy.ops.shapedeform.unbind() == {"FINISHED"}
    assert not any(o.shapedeform.rig is not None and o.shapedeform.rig.name == name for o in bpy.data.objects)


def test_a_build_modifier_after_the_rig_is_named_among_what_stroke_order_drops(addon):
    """Stroke Order's rebuilt drawings start at frame 0: a Build modifier after the rig's drew
    nothing on any frame. The sidebar names it; before the rig's it is unaffected."""
    grease_pencil = addon.shapedeform_addon.sources.grease_pencil
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    monkey = bpy.context.active_object
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    assert grease_pencil.stroke_order_losses(monkey) == []
    build = monkey.modifiers.new("Build", "GREASE_PENCIL_BUILD")
    assert grease_pencil.stroke_order_losses(monkey) == ["the keyframe timing read by 'Build'"]
    monkey.modifiers.move(len(monkey.modifiers) - 1, 0)
    assert monkey.modifiers[0] == build and grease_pencil.stroke_order_losses(monkey) == []
    # Noise's Random re-seeds every few frames counted from the keyframe: named too (a rig at
    # rest moved its points 0.05 on a drawing 3 tall).
    noise = monkey.modifiers.new("Noise", "GREASE_PENCIL_NOISE")
    assert grease_pencil.stroke_order_losses(monkey) == ["the keyframe timing read by 'Noise'"]
    # Seeds and offsets counted by stroke or layer change while a pose folds (QA: Offset by layer
    # moved the body 0.10, by stroke 0.05; Noise's seed the eye 0.006): named too.
    noise.use_random = False
    assert grease_pencil.stroke_order_losses(monkey) == ["the layer and stroke order read by 'Noise'"]
    monkey.modifiers.remove(noise)
    offset = monkey.modifiers.new("Offset", "GREASE_PENCIL_OFFSET")
    for mode, named in (("LAYER", True), ("STROKE", True), ("RANDOM", True), ("MATERIAL", False)):
        offset.offset_mode = mode
        assert grease_pencil.stroke_order_losses(monkey) == (
            ["the layer and stroke order read by 'Offset'"] if named else []), mode
    monkey.modifiers.remove(offset)
    # A modifier pinned last comes after the rig's: seen before Bind adds the rig's (which
    # turned Stroke Order on under a Build pinned last).
    bpy.ops.object.grease_pencil_add(type="MONKEY")
    late = bpy.context.active_object
    build = late.modifiers.new("Build", "GREASE_PENCIL_BUILD")
    build.use_pin_to_last = True
    assert grease_pencil.stroke_order_losses(late) == ["the keyframe timing read by 'Build'"]
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    modifier = addon.shapedeform_addon.rig_format.modifiers_of(late)[0]
    order = addon.shapedeform_addon.nodes.input_identifiers(modifier.node_group)["Stroke Order"]
    assert addon.shapedeform_addon.compat.modifier_input(modifier, order) is False


def test_the_remove_button_removes_the_entry_of_a_handle_deleted_for_good(addon):
    """The list shows a handle deleted for good as deleted until "-" removes it; but "-" named
    the active item's Empty, which such an entry no longer has, so it refused ("Select the
    handles to remove") and the entry stayed."""
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    kept = checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    gone = checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    bpy.data.objects.remove(gone)
    obj.shapedeform["active_handle"] = 1
    bpy.context.view_layer.objects.active = obj
    layout = RecordingLayout()
    bpy.types.SHAPEDEFORM_PT_panel.draw(SimpleNamespace(layout=layout), bpy.context)
    minus = next(given for idname, given in layout.buttons if idname == "shapedeform.remove_handle")
    assert bpy.ops.shapedeform.remove_handle(**vars(minus)) == {"FINISHED"}
    assert [item.object for item in obj.shapedeform.handles] == [kept]
    assert obj.shapedeform.active_handle == 0


def test_the_panel_of_a_baked_rig_whose_saved_data_a_script_damaged_still_draws(addon, capfd):
    """Asking whether the bake is out of date reads every handle's saved data: with a handle's
    offsets deleted by a script it raised, and the panel lost Bake Again and Clear Bake."""
    obj = grid()
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.shapedeform.bind() == {"FINISHED"}
    checks.add_handle(obj, checks.world(obj, [-1.0, 0.0, 0.0]))
    checks.add_handle(obj, checks.world(obj, [1.0, 0.0, 0.0]))
    assert addon.shapedeform_addon.bake.bake_objects([obj], 1, 2) == [obj]
    del obj.shapedeform.handles[0][addon.shapedeform_addon.rig_format.HANDLE_OFFSETS]
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = obj
    items = drawn(bpy.context)
    assert "shapedeform.clear_bake" in items and "shapedeform.bake" in items
    capfd.readouterr()
