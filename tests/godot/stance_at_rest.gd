## A character whose controller has `stance_pose` set before it enters the tree (as the inspector sets it) stands in
## the stance's guard without being asked to punch, and turns into the other stance, or back to the square guard, when
## a game sets `stance` or `stance_pose` while it is idle. Prints, after each second, how far the torso is turned
## (degrees about the character's up axis, positive to its left) and the signals heard, as `STANCE_AT_REST <json>`.
extends SceneTree

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")
const STEP_FRAMES := 120

var _character: Node3D
var _controller: Node
var _frame := 0
var _report := {"turn_deg": [], "signals": []}


func _initialize() -> void:
	_character = CHARACTER_SCENE.instantiate()
	root.add_child(_character)
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.position = PunchSpec.default_target_offset()
	root.add_child(sandbag)
	_controller = ClassDB.instantiate("PunchController")
	_controller.set("character", _character)
	_controller.set("target", sandbag.get_node("Bag"))
	_controller.set("stance_pose", true)
	root.add_child(_controller)
	for name in ["punch_started", "recovered", "staggered", "knocked_down"]:
		_controller.connect(name, func(_a = null, _b = null, _c = null): _report.signals.append(name))


func _physics_process(_delta: float) -> bool:
	_frame += 1
	if _frame % STEP_FRAMES != 0:
		return false
	var torso: Node3D = _character.get_node("Torso")
	var turn := (_character.global_basis.inverse() * torso.global_basis).get_rotation_quaternion().get_euler().y
	_report.turn_deg.append(snappedf(rad_to_deg(turn), 0.1))
	match _frame / STEP_FRAMES:
		1:
			_controller.set("stance", PunchController.SOUTHPAW)
		2:
			_controller.set("stance_pose", false)
		3:
			print("STANCE_AT_REST ", JSON.stringify(_report))
			quit(0)
	return false
