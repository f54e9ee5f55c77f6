## The knock-down hand-off on a game's own character: a converted CC0 character (--glb=PATH) wired by the editor
## plugin's action (`own_character_setup.gd`), with a ragdoll of the game's own under its skeleton (a
## PhysicalBoneSimulator3D whose PhysicalBone3D capsules sit on the spine, neck, head and arm bones, as Godot's
## "Create Physical Skeleton" makes them), turned 130 degrees, is struck hard enough to be knocked down. Its twin, facing
## ahead, has no ragdoll.
## Recorded: the part and the rig's bone `hit_taken` names (and the rig's chest bone), when `knocked_down` came, whether the modifier handed the skeleton to the simulator
## (`handed_off_to`) and the simulator simulates, the head bone's physical velocity at the hand-off against the
## simulated head's, how far the head bone fell while handed off (no floor: the ragdoll, not the simulated body
## hanging on its pelvis, holds the skeleton then), and after
## `recover()` whether the simulation stopped and the modifier poses the skeleton again (and the head is back where it
## stood once `recovered`); for the twin, that
## nothing was handed off and its skeleton shows the simulated body hanging limp.
##
## Prints `KNOCKDOWN_RAGDOLL <json>` and quits.
extends SceneTree

const Setup := preload("res://addons/punch_controller/own_character_setup.gd")
## The hit: from the front, at the chest, above the knock-down threshold (320 N s by default).
const IMPULSE_NS := 400.0
const DOWN_S := 1.0

var _report := {}


func _initialize() -> void:
	var glb := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--glb="):
			glb = argument.trim_prefix("--glb=")
	_run.call_deferred(glb)


func _run(glb: String) -> void:
	var with_ragdoll := _fighter(glb, Vector3(0, 0, 0), 130.0, true)
	var without := _fighter(glb, Vector3(6, 0, 0), 0.0, false)
	if with_ragdoll.is_empty() or without.is_empty():
		print("KNOCKDOWN_RAGDOLL_SETUP_FAILED ", glb)
		quit(1)
		return
	for _i in 60:  # ready, sized to the rig, standing in guard
		await physics_frame
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.standing_head_y = fighter.head_y
	for fighter: Dictionary in [with_ragdoll, without]:
		var chest: Node3D = fighter.character.get_node("Torso")
		var push: Vector3 = -fighter.character.global_basis.z * IMPULSE_NS  # from the front: toward its back
		fighter.push = push.normalized()
		fighter.character.take_hit(&"torso", push, chest.global_position + Vector3(0, 0.1, 0))
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.report.knocked_down = fighter.knocked
	await physics_frame
	await physics_frame
	_after_hand_off(with_ragdoll)
	_after_hand_off(without)
	var start_y: float = with_ragdoll.head_y
	var start_y_without: float = without.head_y
	var weights: Array[float] = []
	var frames := int(DOWN_S * Engine.physics_ticks_per_second)
	for _i in frames:
		await physics_frame
		weights.append(without.modifier.blend_weight())
	with_ragdoll.report.head_fell_m = start_y - with_ragdoll.head_y
	with_ragdoll.report.still_handed_off = with_ragdoll.modifier.handed_off_to() == with_ragdoll.simulator
	without.report.head_fell_m = start_y_without - without.head_y
	without.report.limp_blend_weight = weights.max()
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.controller.recover()
	for _i in 3:
		await physics_frame
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.report.after_recover_handed_off = fighter.modifier.handed_off_to() != null
		fighter.report.after_recover_simulating = fighter.simulator != null and fighter.simulator.is_simulating_physics()
		fighter.report.after_recover_blend_weight = fighter.modifier.blend_weight()
	for _i in 240:
		await physics_frame
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.report.recovered = fighter.recovered
		fighter.report.head_back_m = fighter.head_y - fighter.standing_head_y
	_report.with_ragdoll = with_ragdoll.report
	_report.without = without.report
	for fighter: Dictionary in [with_ragdoll, without]:
		fighter.undo.free()
	print("KNOCKDOWN_RAGDOLL ", JSON.stringify(_report))
	quit(0)


## A level with the model at `at`, turned `yaw_deg` about the vertical, wired by the plugin's action; with `ragdoll`, a PhysicalBoneSimulator3D of
## capsules on the mapped upper-body bones under its skeleton.
func _fighter(glb: String, at: Vector3, yaw_deg: float, ragdoll: bool) -> Dictionary:
	var level := Node3D.new()
	level.position = at
	root.add_child(level)
	var document := GLTFDocument.new()
	var state := GLTFState.new()
	if document.append_from_file(glb, state) != OK:
		return {}
	var model: Node3D = document.generate_scene(state)
	model.rotation_degrees.y = yaw_deg
	level.add_child(model)
	var skeleton := Setup.find_skeleton(level, [])
	var undo := UndoRedo.new()
	var made: Dictionary = Setup.make_skeleton_punch(level, skeleton, undo)
	if not made.ok:
		undo.free()
		return {}
	var controller: Node = level.get_node("PunchController")
	var modifier: Node = skeleton.get_children().filter(func(n): return n.is_class("PunchSkeletonModifier"))[0]
	var fighter := {"controller": controller, "character": controller.get("character"), "modifier": modifier,
		"skeleton": skeleton, "simulator": null, "knocked": [], "recovered": false, "report": {}, "head_y": 0.0,
		"standing_head_y": 0.0, "undo": undo}
	# The pose a modifier writes holds only until the frame is drawn: read it when the skeleton says it is done.
	var head := skeleton.find_bone(modifier.get("bone_map")["head"])
	skeleton.skeleton_updated.connect(func():
		fighter.head_y = (skeleton.global_transform * skeleton.get_bone_global_pose(head)).origin.y)
	controller.set("target", null)
	controller.knocked_down.connect(func(impulse_ns: float): fighter.knocked.append(impulse_ns))
	controller.recovered.connect(func(): fighter.recovered = true)
	fighter.character.hit_taken.connect(func(part, _impulse, _point, _from, bone):
		fighter.report.hit_taken = [part, bone]
		fighter.report.chest_bone = modifier.get("bone_map")["chest"])
	if ragdoll:
		fighter.simulator = _ragdoll(skeleton, modifier.get("bone_map"))
	return fighter


## Capsules on the spine (the bones between the hips and the chest), neck, head, upper arms and forearms, each
## jointed to its parent bone's (cone joints, as Godot's "Create Physical Skeleton" makes them).
func _ragdoll(skeleton: Skeleton3D, bone_map: Dictionary) -> PhysicalBoneSimulator3D:
	var simulator := PhysicalBoneSimulator3D.new()
	simulator.name = "PhysicalBoneSimulator3D"
	skeleton.add_child(simulator)
	var bones: Array[int] = []
	var chest := skeleton.find_bone(bone_map["chest"])
	var hips := skeleton.find_bone(bone_map["hips"])
	var bone := chest
	while bone != -1 and bone != hips:
		bones.push_front(bone)
		bone = skeleton.get_bone_parent(bone)
	for role in ["neck", "head", "upper_arm_l", "forearm_l", "upper_arm_r", "forearm_r"]:
		if bone_map.get(role, "") != "":
			bones.append(skeleton.find_bone(bone_map[role]))
	for index in bones:
		var physical := PhysicalBone3D.new()
		physical.name = "Physical_" + skeleton.get_bone_name(index)
		physical.bone_name = skeleton.get_bone_name(index)
		physical.joint_type = PhysicalBone3D.JOINT_TYPE_CONE if index != bones[0] else PhysicalBone3D.JOINT_TYPE_NONE
		physical.mass = 3.0
		physical.collision_layer = 1 | 2  # the world's and the simulated bodies' layers: only the exceptions keep them apart
		var shape := CollisionShape3D.new()
		var capsule := CapsuleShape3D.new()
		capsule.radius = 0.05
		capsule.height = 0.2
		shape.shape = capsule
		physical.add_child(shape)
		simulator.add_child(physical)
	return simulator


## After the hit's first frames: whether the skeleton was handed off, and the head bone's velocity then against the
## simulated head's.
func _after_hand_off(fighter: Dictionary) -> void:
	var simulator: PhysicalBoneSimulator3D = fighter.simulator
	fighter.report.handed_off = fighter.modifier.handed_off_to() != null and fighter.modifier.handed_off_to() == simulator
	fighter.report.simulating = simulator != null and simulator.is_simulating_physics()
	if simulator == null:
		return
	var head_bone: String = fighter.modifier.get("bone_map")["head"]
	var physical: PhysicalBone3D = simulator.get_node("Physical_" + head_bone)
	var simulated: RigidBody3D = fighter.character.get_node("Head")
	fighter.report.head_bone_speed_mps = physical.linear_velocity.length()
	fighter.report.simulated_head_speed_mps = simulated.linear_velocity.length()
	fighter.report.head_bone_along_push = physical.linear_velocity.normalized().dot(fighter.push)

