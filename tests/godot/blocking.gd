## `PunchController.block()` as a game calls it, on one character standing in guard: a block of 0.5 s (where the fists
## are while it holds and after it, `is_blocking()` along the way), a block held until `stop_blocking()`, a punch asked
## for during a block, and blocks refused (seconds not a number; a knocked-down character); the elbow motor's torque
## limit along the way (a block braces the guard); and a second character, turned, with its head sized 6 cm higher on
## its neck (`size_head`, as an own rig's), blocking too; and a third, its target 35° to its right, blocking turned
## toward it, then still blocking as the target goes round to 35° to its left. Prints `BLOCKING <json>` and quits.
extends SceneTree

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")

var _character: Node3D
var _controller: Node
var _tall_headed: Node3D
var _tall_headed_controller: Node
var _facing: Node3D
var _facing_controller: Node
var _opponent: Node3D
var _frame := 0
var _report := {"signals": [], "samples": {}}


func _initialize() -> void:
	_character = CHARACTER_SCENE.instantiate()
	root.add_child(_character)
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.position = PunchSpec.default_target_offset()
	root.add_child(sandbag)
	_controller = ClassDB.instantiate("PunchController")
	_controller.set("character", _character)
	_controller.set("target", sandbag.get_node("Bag"))
	_controller.set("policy", load("res://addons/punch_controller/policies/straight.onnx"))
	root.add_child(_controller)
	_tall_headed = CHARACTER_SCENE.instantiate()
	# Turned 130 degrees (the guard is read in its own frame): not only the set-up the high guard was measured in.
	_tall_headed.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(130.0)), Vector3(3, 0, 0))
	root.add_child(_tall_headed)
	_tall_headed_controller = ClassDB.instantiate("PunchController")
	_tall_headed_controller.set("character", _tall_headed)
	_tall_headed_controller.set("policy", load("res://addons/punch_controller/policies/straight.onnx"))
	root.add_child(_tall_headed_controller)
	_facing = CHARACTER_SCENE.instantiate()
	_facing.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(-70.0)), Vector3(-3, 0, 0))
	root.add_child(_facing)
	_opponent = Node3D.new()  # 35° to its right (-X in its frame), 1 m away, chest high
	_opponent.position = _facing.transform * (Vector3(-sin(deg_to_rad(35.0)), 1.3, cos(deg_to_rad(35.0))))
	root.add_child(_opponent)
	_facing_controller = ClassDB.instantiate("PunchController")
	_facing_controller.set("character", _facing)
	_facing_controller.set("target", _opponent)
	_facing_controller.set("policy", load("res://addons/punch_controller/policies/straight.onnx"))
	root.add_child(_facing_controller)
	for name in ["punch_started", "punch_finished", "recovered"]:
		_controller.connect(name, func(_a = null, _b = null, _c = null): _report.signals.append([name, _frame]))


## The fists (their centres) and the head's centre in the character's frame: +Z ahead, +Y up.
func _sample(label: String, character: Node3D = _character, controller: Node = _controller) -> void:
	var to_local := character.global_transform.affine_inverse()
	_report.samples[label] = {
		"blocking": controller.call("is_blocking"),
		"head": _vector(to_local * (character.get_node("Head/HeadMesh") as Node3D).global_position),
		"fists": [_vector(to_local * (character.get_node("ForearmL/FistL") as Node3D).global_position),
			_vector(to_local * (character.get_node("ForearmR/FistR") as Node3D).global_position)],
		"elbow_torque_nm": _motor_torque_nm(character.get_node("ElbowR")),
	}


## The largest motor torque limit on any axis of `joint` as the physics engine has it now (N m).
func _motor_torque_nm(joint: Node) -> float:
	var largest := 0.0
	for axis in [Vector3.AXIS_X, Vector3.AXIS_Y, Vector3.AXIS_Z]:
		largest = maxf(largest, PhysicsServer3D.generic_6dof_joint_get_param(joint.get_rid(), axis,
			PhysicsServer3D.G6DOF_JOINT_ANGULAR_MOTOR_FORCE_LIMIT))
	return snappedf(largest, 0.01)


func _vector(v: Vector3) -> Array:
	return [snappedf(v.x, 0.001), snappedf(v.y, 0.001), snappedf(v.z, 0.001)]


func _physics_process(_delta: float) -> bool:
	_frame += 1
	match _frame:
		5:
			_report.head_sized = _tall_headed.call("size_head", _tall_headed.call("shoulder_to_crown_m") + 0.06)
		10:
			_sample("guard")
			_report.blocked = _controller.call("block", 0.5)
			_tall_headed_controller.call("block", 0.5)
			_facing_controller.call("block", 1.0)
		50:  # 1/3 s into the block
			_sample("blocking")
			_sample("tall_headed_blocking", _tall_headed, _tall_headed_controller)
			_sample("facing_blocking", _facing, _facing_controller)
			# The opponent goes round to the other side: the block's trunk follows it.
			_opponent.position = _facing.transform * (Vector3(sin(deg_to_rad(35.0)), 1.3, cos(deg_to_rad(35.0))))
		110:  # half a second later, the block still holding
			_sample("facing_followed", _facing, _facing_controller)
		150:  # 0.75 s after the block's end
			_sample("after")
			_controller.call("block")  # until stopped
		400:
			_sample("held")
			_controller.call("stop_blocking")
		500:
			_sample("stopped")
			_controller.call("block")
		530:
			_report.punched = _controller.call("punch")
			_report.blocking_after_punch = _controller.call("is_blocking")
		700:
			_report.refused = _controller.call("block", NAN)
			var chest: Vector3 = (_character.get_node("Torso") as Node3D).global_position
			_character.call("take_hit", &"torso", -_character.global_basis.z * 400.0, chest)
		720:
			_report.knocked_down = _controller.call("is_knocked_down")
			_report.refused_when_down = _controller.call("block")
			print("BLOCKING ", JSON.stringify(_report))
			quit(0)
	return false
