## The reach volume in the game (demo straight policy): four characters, each turned and moved, with a
## sandbag at the policy's default offset ("inside"), 0.4 m to its left (0.15 m beside the volume: "beside"),
## 1.4 m ahead ("far") and 0.6 m above its head ("high"); a fifth with arms 0.75 times the body's, the sandbag at
## 0.06 m beyond the default offset, inside the policy's volume ("short_arms").
## Records `target_out_of_reach` (offset and nearest point, turned back into the character's frame), `reaches()`
## at the sandbag, whether punch() started, the punch's hits and each controller's `reach_volume()`; prints
## `REACH <json>` and quits.
extends SceneTree

const POLICY := "res://addons/punch_controller/policies/straight.onnx"
const CASES := {"inside": Vector3.ZERO, "beside": Vector3(0.4, 0, 0), "far": Vector3(0, 0, 0.68),
	"high": Vector3(0, 0.9, 0), "short_arms": Vector3(0, 0, 0.06)}
const SHORT_ARM_SCALE := 0.75
var _report := {}
var _pending := 0
var _short_armed: Node


func _initialize() -> void:
	var index := 0
	for name in CASES:
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.position = Vector3(5.0 * index, 0, -2.0)
		character.rotation.y = 0.7 * index
		root.add_child(character)
		var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
		sandbag.position = character.transform * (PunchSpec.default_target_offset() + CASES[name])
		root.add_child(sandbag)
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", sandbag.get_node("Bag"))
		controller.set("policy", load(POLICY))
		controller.set("auto_recover", false)
		_report[name] = {"out_of_reach": [], "hits": -1}
		controller.connect("target_out_of_reach", func(offset: Vector3, nearest: Vector3):
			var local := character.global_transform.affine_inverse() * nearest
			_report[name].out_of_reach.append([offset.x, offset.y, offset.z, local.x, local.y, local.z]))
		controller.connect("punch_finished", func(metrics: Dictionary):
			_report[name].hits = metrics.hits
			_report[name].reach_volume = _reach_of(controller)
			_pending -= 1
			if _pending == 0:
				_finish())
		root.add_child(controller)
		controller.ready.connect(func():
			if name == "short_arms":
				character.call("size_arms", 0.282 * SHORT_ARM_SCALE, 0.337 * SHORT_ARM_SCALE, 0.36)
				_short_armed = controller
			_report[name].reaches = controller.call("reaches", &"", sandbag.get_node("Bag").global_position)
			_report[name].started = controller.call("punch"))
		_pending += 1
		index += 1


func _reach_of(controller: Node, move := &"") -> Dictionary:
	var reach: Dictionary = controller.call("reach_volume", move)
	var result := {}
	for key in reach:
		var value = reach[key]
		result[key] = [value.x, value.y] if value is Vector2 else value
	return result


func _finish() -> void:
	# The short arms in the stance's guard: each hand's moves of the stance's moveset.
	_short_armed.set("stance_pose", true)
	_report["short_arms_stance"] = {}
	var character: Node3D = _short_armed.get("character")
	for move in [&"jab", &"cross", &"lead_hook", &"rear_hook"]:
		var reach := _reach_of(_short_armed, move)
		# `reaches()` at the far end of the move's volume (its middle height and side) and 5 cm beyond it.
		var middle := Vector3((reach.side_m[0] + reach.side_m[1]) / 2, (reach.height_m[0] + reach.height_m[1]) / 2, 0)
		reach["reaches_far_end"] = _short_armed.call("reaches", move,
				character.global_transform * (middle + Vector3(0, 0, reach.distance_m[1] - 0.01)))
		reach["reaches_beyond"] = _short_armed.call("reaches", move,
				character.global_transform * (middle + Vector3(0, 0, reach.distance_m[1] + 0.05)))
		_report["short_arms_stance"][move] = reach
	print("REACH ", JSON.stringify(_report))
	quit()
