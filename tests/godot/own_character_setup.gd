## The editor plugin's "Make Selected Skeleton Punch" (`own_character_setup.gd`), run headless with a plain
## UndoRedo in place of the editor's: a converted CC0 character (--glb=PATH, loaded with GLTFDocument as a game's
## imported model, turned and moved, with an AnimationPlayer) in a level scene gets its modifier, simulated
## character, sandbag and controller as one action, which undoes, redoes and saves (PackedScene.pack), also when
## the model is instanced from a scene file without Editable Children (the action turns them on); a skeleton
## with meaningless bone names gets the modifier's message and nothing added; two skeletons and none are refused.
## Then the character punches the sandbag the action placed (--policy is not needed: the action picks the addon's
## straight policy).
##
## Prints `OWN_CHARACTER_SETUP <json>` and quits.
extends SceneTree

const Setup := preload("res://addons/punch_controller/own_character_setup.gd")

var _report := {}


## Reads --glb=PATH and runs the steps once the tree is up.
func _initialize() -> void:
	var glb := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--glb="):
			glb = argument.trim_prefix("--glb=")
	_run.call_deferred(glb)


## Each step in turn; the punch over physics frames.
func _run(glb: String) -> void:
	var level := Node3D.new()
	level.name = "Level"
	level.position = Vector3(0.5, 0, 0)
	root.add_child(level)
	_report.no_skeleton = _refused(level, null)

	var document := GLTFDocument.new()
	var state := GLTFState.new()
	if document.append_from_file(glb, state) != OK:
		print("OWN_CHARACTER_SETUP_GLB_FAILED ", glb)
		quit(1)
		return
	var rig: Node3D = document.generate_scene(state)
	rig.name = "Model"
	rig.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(30.0)), Vector3(1.0, 0.0, -2.0))
	level.add_child(rig)
	var player := AnimationPlayer.new()
	player.name = "AnimationPlayer"
	rig.add_child(player)
	_own(rig, level)
	var skeleton := Setup.find_skeleton(level, [])
	_report.found_alone = skeleton != null
	_report.found_from_model = Setup.find_skeleton(level, [rig]) == skeleton

	var children_before := level.get_child_count()
	var undo := UndoRedo.new()
	var made := Setup.make_skeleton_punch(level, skeleton, undo)
	_report.ok = made.ok
	if not made.ok:
		_report.message = made.message
		_finish(undo)
		return
	var controller: Node = made.controller
	var character: Node3D = made.character
	var sandbag: Node3D = made.sandbag
	var modifier: Node = made.modifier
	_report.added = level.get_child_count() - children_before
	_report.nodes = _describe(level, skeleton, controller, character, sandbag, modifier, player)
	undo.undo()
	_report.after_undo = {"added": level.get_child_count() - children_before,
		"modifiers": _modifiers(skeleton), "player_physics": _physics(player),
		"in_tree": [controller.is_inside_tree(), character.is_inside_tree(), sandbag.is_inside_tree(), modifier.is_inside_tree()]}
	undo.redo()
	_report.after_redo = _describe(level, skeleton, controller, character, sandbag, modifier, player)
	_report.saved = _saved(level)

	# A second rig whose bones have meaningless names: refused with the modifier's words, nothing added.
	var unnamed := _unnamed_rig()
	level.add_child(unnamed)
	_own(unnamed, level)
	var unnamed_skeleton: Skeleton3D = unnamed.get_node("Skeleton3D")
	children_before = level.get_child_count()
	var refused := Setup.make_skeleton_punch(level, unnamed_skeleton, undo)
	_report.unnamed = {"ok": refused.ok, "message": refused.get("message", ""),
		"added": level.get_child_count() - children_before, "skeleton_children": unnamed_skeleton.get_child_count(),
		"history": undo.get_history_count()}
	_report.two_skeletons = _refused(level, null)
	unnamed.free()

	# The same model instanced from a scene file without Editable Children, as dropped into a level in the editor:
	# the action turns them on, so that the modifier under its Skeleton3D is saved with the level.
	_report.instanced = _instanced(document.generate_scene(state))

	# The set-up character punches its sandbag.
	var landed := {"hits": 0, "on_bag": 0, "finished": false}
	var bag := sandbag.get_node("Bag")
	controller.connect("hit", func(_impulse, _speed, _position, body, _push, _hand, _part, _blocked):
		landed.hits += 1
		landed.on_bag += int(body == bag))
	controller.connect("punch_finished", func(_metrics): landed.finished = true)
	var placed := character.global_transform
	for frame in 4:
		await physics_frame
	# Where the modifier's follow_rig keeps the simulated body, against where the action put it.
	_report.placement_gap_m = character.global_position.distance_to(placed.origin)
	_report.placement_turn_rad = placed.basis.get_rotation_quaternion().angle_to(
		character.global_basis.get_rotation_quaternion())
	_report.punch_started = controller.call("punch")
	for frame in 240:
		await physics_frame
		if landed.finished:
			break
	_report.punch = landed
	_report.written_bones = PunchProbe.written_bones(modifier).size()
	_finish(undo)


## What the scene holds after the action: parents, owners, the wiring, the mapping, the animation's callback.
func _describe(level: Node3D, skeleton: Skeleton3D, controller: Node, character: Node3D, sandbag: Node3D,
		modifier: Node, player: AnimationPlayer) -> Dictionary:
	var bone_map: Dictionary = modifier.get("bone_map")
	var policy: Resource = controller.get("policy")
	return {
		"parents": [controller.get_parent() == level, character.get_parent() == level, sandbag.get_parent() == level,
			modifier.get_parent() == skeleton],
		"owners": [controller.owner == level, character.owner == level, sandbag.owner == level, modifier.owner == level],
		"character_class": character.get_class(),
		"controller_character": controller.get("character") == character,
		"controller_target": controller.get("target") == sandbag.get_node("Bag"),
		"policy": policy.resource_path if policy else "",
		"modifier_controller": modifier.get("controller") == controller,
		"size_to_rig": modifier.get("size_to_rig"),
		"mapped": modifier.call("is_mapped"),
		"bone_map": bone_map,
		"warnings": modifier.call("configuration_warnings"),
		"modifiers": _modifiers(skeleton),
		"player_physics": _physics(player),
		# The bag in the character's frame: where the policies were trained to find it.
		"bag_in_character": _array(character.global_transform.affine_inverse() * sandbag.get_node("Bag").global_position),
		"default_offset": _array(PunchSpec.default_target_offset()),
	}


## `v` as a JSON array.
func _array(v: Vector3) -> Array:
	return [v.x, v.y, v.z]


## The PunchSkeletonModifiers under `skeleton`.
func _modifiers(skeleton: Skeleton3D) -> int:
	return skeleton.get_children().filter(func(c): return c is PunchSkeletonModifier).size()


## Whether `player` processes in physics frames.
func _physics(player: AnimationPlayer) -> bool:
	return player.callback_mode_process == AnimationMixer.ANIMATION_CALLBACK_MODE_PROCESS_PHYSICS


## The level packed as a scene file would save it, instantiated again: what of the set-up came along.
func _saved(level: Node3D) -> Dictionary:
	var scene := PackedScene.new()
	var packed := scene.pack(level) == OK
	var copy := scene.instantiate()
	var modifiers := copy.find_children("*", "PunchSkeletonModifier", true, false)
	var controllers := copy.find_children("*", "PunchController", true, false)
	var saved := {"packed": packed, "modifiers": modifiers.size(), "controllers": controllers.size(),
		"modifier_under_skeleton": modifiers.size() == 1 and modifiers[0].get_parent() is Skeleton3D,
		"characters": copy.find_children("*", "PunchCharacter", true, false).size(),
		"bags": copy.find_children("Bag", "RigidBody3D", true, false).size()}
	copy.free()
	return saved


## Saves `model` as a scene file, instances it into a new level (its children not editable) and sets it up.
func _instanced(model: Node3D) -> Dictionary:
	model.name = "Model"
	for child in model.get_children():
		_own(child, model)
	var file := PackedScene.new()
	file.pack(model)
	model.free()
	var path := "user://own_character_setup_model.tscn"
	ResourceSaver.save(file, path)
	var instance: Node3D = (load(path) as PackedScene).instantiate(PackedScene.GEN_EDIT_STATE_INSTANCE)
	var level := Node3D.new()
	level.name = "InstancedLevel"
	level.position = Vector3(0, 0, 10)
	root.add_child(level)
	level.add_child(instance)
	instance.owner = level
	var undo := UndoRedo.new()
	var skeleton := Setup.find_skeleton(level, [instance])
	var made := Setup.make_skeleton_punch(level, skeleton, undo)
	var result := {"ok": made.ok, "made_editable": made.get("made_editable", []).map(func(n): return String(n.name)),
		"editable": level.is_editable_instance(instance), "saved_modifiers": _saved(level).modifiers}
	undo.undo()
	result.undone_editable = level.is_editable_instance(instance)
	level.free()
	undo.free()
	DirAccess.remove_absolute(path)
	return result


## The message the action gives for the level as it is, with no skeleton chosen.
func _refused(level: Node3D, undo: Object) -> String:
	var made := Setup.make_skeleton_punch(level, Setup.find_skeleton(level, []), undo)
	return "" if made.ok else made.message


## Owns every node under `node` by `owner`, as a scene made local in the editor is.
func _own(node: Node, owner: Node) -> void:
	for child in node.get_children():
		child.owner = owner
		_own(child, owner)
	node.owner = owner


## A humanoid-shaped skeleton whose bones are named Bone0, Bone1, ...: no role can be found by name.
func _unnamed_rig() -> Node3D:
	var rig := Node3D.new()
	rig.name = "Unnamed"
	rig.position = Vector3(-5, 0, 0)
	var skeleton := Skeleton3D.new()
	skeleton.name = "Skeleton3D"
	rig.add_child(skeleton)
	# hips, spine, chest, head; per side an upper arm, forearm and hand
	var bones := [[-1, Vector3(0, 1.0, 0)], [0, Vector3(0, 1.2, 0)], [1, Vector3(0, 1.35, 0)], [2, Vector3(0, 1.6, 0)],
		[2, Vector3(0.18, 1.42, 0)], [4, Vector3(0.46, 1.42, 0)], [5, Vector3(0.73, 1.42, 0)],
		[2, Vector3(-0.18, 1.42, 0)], [7, Vector3(-0.46, 1.42, 0)], [8, Vector3(-0.73, 1.42, 0)]]
	for i in bones.size():
		skeleton.add_bone("Bone%d" % i)
	for i in bones.size():
		var parent: int = bones[i][0]
		skeleton.set_bone_parent(i, parent)
		skeleton.set_bone_rest(i, Transform3D(Basis(), bones[i][1] - (bones[parent][1] if parent >= 0 else Vector3.ZERO)))
	skeleton.reset_bone_poses()
	return rig


## Frees the UndoRedo, prints the report and quits.
func _finish(undo: UndoRedo) -> void:
	undo.free()
	print("OWN_CHARACTER_SETUP ", JSON.stringify(_report))
	quit(0)
