@tool
## Makes a game's own rigged character punch, as the README's "Your own character" says to do by hand, in one
## undoable action: the addon's simulated PunchCharacter (placed on the rig, where the modifier's `follow_rig`
## puts it), a sandbag in front of it where the policies are trained to find it, a PunchController wired to both
## with the straight policy, and a PunchSkeletonModifier under the rig's Skeleton3D pointing at the controller (its
## `size_to_rig` sizes the simulated arms to the rig's before the first punch). The rig's AnimationPlayers and
## AnimationTrees are switched to physics process, as step 1 of the README asks. A skeleton inside an instanced
## model (an imported .glb or a .tscn dropped into the scene) gets the model's Editable Children turned on in the
## same action, as the editor's menu would: a node added under a model whose children are not editable is not
## saved with the scene. A skeleton whose bones the modifier cannot map gets the modifier's own message, and
## nothing is added.
## Used by the editor plugin (Project > Tools > "Make Selected Skeleton Punch"); tests call it with an UndoRedo.
extends RefCounted

const CHARACTER_SCENE := "res://addons/punch_controller/scenes/punch_character.tscn"
const SANDBAG_SCENE := "res://addons/punch_controller/scenes/punch_sandbag.tscn"
const DEFAULT_POLICY := "res://addons/punch_controller/policies/straight.onnx"
const ACTION := "Make Skeleton Punch"


## The skeleton to set up: a selected Skeleton3D, else the only Skeleton3D under the selected nodes, else the
## scene's only Skeleton3D; null when there is none or more than one to choose from.
static func find_skeleton(root: Node, selected: Array) -> Skeleton3D:
	var skeletons: Array[Node] = []
	for node in selected:
		if node is Skeleton3D:
			skeletons.append(node)
	if skeletons.is_empty():
		for node in selected:
			if node is Node:
				skeletons.append_array(node.find_children("*", "Skeleton3D", true, false))
	if skeletons.is_empty() and root != null:
		skeletons = root.find_children("*", "Skeleton3D", true, false)
		if root is Skeleton3D:
			skeletons.push_front(root)
	return skeletons[0] if skeletons.size() == 1 else null


## Why the scene cannot be set up with `skeleton` ("" when it can): no 3D scene, no skeleton (or several), a
## skeleton that has a PunchSkeletonModifier already.
static func scene_problem(root: Node, skeleton: Skeleton3D) -> String:
	if not root is Node3D:
		return "open a 3D scene first (its root must be a Node3D)."
	if not ClassDB.class_exists("PunchSkeletonModifier"):
		return "the GDExtension is not loaded (see the README, 'Building the extension')."
	if skeleton == null:
		var count := root.find_children("*", "Skeleton3D", true, false).size() + int(root is Skeleton3D)
		if count == 0:
			return ("this scene has no Skeleton3D. Put your rigged model in it (with Editable Children on, so that "
				+ "its Skeleton3D can be reached), then select its Skeleton3D.")
		return "this scene has %d Skeleton3D nodes: select the one to make punch." % count
	for child in skeleton.get_children():
		if child.is_class("PunchSkeletonModifier"):
			return "'%s' has a PunchSkeletonModifier already ('%s')." % [skeleton.name, child.name]
	return ""


## Sets up `skeleton` (in the scene under `root`) to punch, as one action of `undo` (the editor's
## EditorUndoRedoManager or an UndoRedo). Returns {"ok": true, "controller", "character", "sandbag", "modifier",
## "made_editable": the instanced models whose Editable Children the action turned on}, or {"ok": false,
## "message": why} with nothing added: a skeleton the modifier cannot map gets the modifier's own words (the roles
## with no bone, and what was looked for).
static func make_skeleton_punch(root: Node, skeleton: Skeleton3D, undo: Object) -> Dictionary:
	var problem := scene_problem(root, skeleton)
	if problem != "":
		return {"ok": false, "message": problem}
	# The modifier maps the bones as it enters the tree: try it under the skeleton, then take it out again.
	var modifier: Node = ClassDB.instantiate("PunchSkeletonModifier")
	modifier.name = "PunchSkeletonModifier"
	skeleton.add_child(modifier)
	var mapped: bool = modifier.call("is_mapped")
	var why: String = modifier.call("mapping_problem")
	var bone_map: Dictionary = modifier.get("bone_map")
	skeleton.remove_child(modifier)
	if not mapped:
		modifier.free()
		return {"ok": false, "message": "'%s' cannot punch: %s. Rename the bones, or add a PunchSkeletonModifier by "
			% [skeleton.name, why if why != "" else "its bones could not be mapped"]
			+ "hand and type the missing bones into its `bone_map`."}

	var character: Node3D = load(CHARACTER_SCENE).instantiate()
	var sandbag: Node3D = load(SANDBAG_SCENE).instantiate()
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.name = "PunchController"
	if ResourceLoader.exists(DEFAULT_POLICY):
		controller.set("policy", load(DEFAULT_POLICY))
	var place := rig_placement(skeleton, bone_map, character)
	var to_root := (root as Node3D).global_transform.affine_inverse()
	character.transform = to_root * place
	# Where the policies train the bag's centre to be, relative to the character (the spec's default).
	var offset: Vector3 = ClassDB.class_call_static("PunchSpec", "default_target_offset")
	sandbag.transform = to_root * Transform3D(place.basis, place * offset)

	var closed := closed_instances(root, skeleton)
	undo.create_action(ACTION)
	for instance in closed:
		_call(undo, root, "set_editable_instance", [instance, true], [instance, false])
	for node in [character, sandbag, controller]:
		_add_child(undo, root, node, root)
	_add_child(undo, skeleton, modifier, root)
	undo.add_do_property(controller, "character", character)
	undo.add_do_property(controller, "target", sandbag.get_node("Bag"))
	undo.add_do_property(modifier, "controller", controller)
	for mixer in _animation_mixers(root, skeleton):
		var physics := AnimationMixer.ANIMATION_CALLBACK_MODE_PROCESS_PHYSICS
		if mixer.callback_mode_process != physics:
			undo.add_do_property(mixer, "callback_mode_process", physics)
			undo.add_undo_property(mixer, "callback_mode_process", mixer.callback_mode_process)
	undo.commit_action()
	return {"ok": true, "controller": controller, "character": character, "sandbag": sandbag, "modifier": modifier,
		"made_editable": closed}


## The instanced scenes between `root` and `skeleton` (their root nodes, outermost last) whose children are not
## editable in `root`'s scene: a node added under one of them would be left out when the scene is saved.
static func closed_instances(root: Node, skeleton: Node) -> Array[Node]:
	var closed: Array[Node] = []
	var node := skeleton
	while node != null and node != root:
		if node.scene_file_path != "" and not root.is_editable_instance(node):
			closed.append(node)
		node = node.get_parent()
	return closed


## Where the PunchSkeletonModifier's `follow_rig` puts the simulated character (global): turned about +Y to face
## the rig's front (its left from the right upper arm to the left one, up from the hips to the head) and with its
## shoulder joints' midpoint on the rig's upper arms' heads, from the bones the modifier mapped (`bone_map`).
static func rig_placement(skeleton: Skeleton3D, bone_map: Dictionary, character: Node3D) -> Transform3D:
	var rest := func(role: String) -> Vector3:
		return skeleton.get_bone_global_rest(skeleton.find_bone(bone_map.get(role, ""))).origin
	var left: Vector3 = (rest.call("upper_arm_l") - rest.call("upper_arm_r")).normalized()
	var up: Vector3 = rest.call("head") - rest.call("hips")
	up = (up - up.dot(left) * left).normalized()
	var front: Vector3 = skeleton.global_basis * left.cross(up)
	var basis := Basis(Vector3.UP, atan2(front.x, front.z))
	var rig_mid: Vector3 = skeleton.global_transform * (0.5 * (rest.call("upper_arm_l") + rest.call("upper_arm_r")))
	var simulated_mid := 0.5 * ((character.get_node("ShoulderR") as Node3D).position
		+ (character.get_node("ShoulderL") as Node3D).position)
	return Transform3D(basis, rig_mid - basis * simulated_mid)


## The AnimationPlayers and AnimationTrees of the model the skeleton belongs to (the skeleton's topmost ancestor
## below the scene's root, and everything under it).
static func _animation_mixers(root: Node, skeleton: Skeleton3D) -> Array[Node]:
	var model: Node = skeleton
	while model.get_parent() != null and model.get_parent() != root and model != root:
		model = model.get_parent()
	var mixers: Array[Node] = model.find_children("*", "AnimationMixer", true, false)
	if model is AnimationMixer:
		mixers.push_front(model)
	return mixers


## Calls `object.method` with `arguments` as part of `undo`'s action, and with `undo_arguments` to undo it (an
## EditorUndoRedoManager or an UndoRedo, as `_add_child`).
static func _call(undo: Object, object: Object, method: String, arguments: Array, undo_arguments: Array) -> void:
	if undo is UndoRedo:
		undo.add_do_method(Callable(object, method).bindv(arguments))
		undo.add_undo_method(Callable(object, method).bindv(undo_arguments))
	else:
		undo.callv("add_do_method", [object, method] + arguments)
		undo.callv("add_undo_method", [object, method] + undo_arguments)


## Adds `node` under `parent`, owned by `owner` (so that the scene saves it), as part of `undo`'s action; takes
## either an EditorUndoRedoManager (object and method) or an UndoRedo (a Callable).
static func _add_child(undo: Object, parent: Node, node: Node, owner: Node) -> void:
	if undo is UndoRedo:
		undo.add_do_method(parent.add_child.bind(node, true))
		undo.add_undo_method(parent.remove_child.bind(node))
	else:
		undo.add_do_method(parent, "add_child", node, true)
		undo.add_undo_method(parent, "remove_child", node)
	undo.add_do_property(node, "owner", owner)
	undo.add_do_reference(node)
