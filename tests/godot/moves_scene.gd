## The moves a game throws by name, in both stances: for each stance and each move the addon's moveset has, a
## character punches a sandbag placed for that move's hand, off the centre line on its side (the left hand's bag is
## the mirror image of the right's); the same again from the stance's guard (`stance_pose`), no moveset set: the
## addon's for the stance (`boxing_stance.tres`). Then what a game gets wrong: a move that is none of the six, a move the
## moveset has no policy for, and a moveset of its own holding one move. Prints `MOVES_SCENE <json>` and quits.
extends SceneTree

const MOVES := [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
const SIDE_M := 0.12  # the bag's centre this far toward the punching hand's side
var _throws: Array[Dictionary] = []
var _report := {"throws": [], "refused": {}}
var _frames := 0


func _initialize() -> void:
	var index := 0
	for stance_pose in [false, true]:
		for stance in [PunchController.ORTHODOX, PunchController.SOUTHPAW]:
			for move in MOVES:
				_throws.append(_add_pair(index, stance, move, stance_pose))
				index += 1


## A character and its bag 3 m from the others; the bag toward the side of the hand `move` is thrown with, at the
## middle of the move's reach (`reach_volume(move)`). With
## `stance_pose`, the character stands in the stance's guard and throws from the stance's moveset (the default then).
func _add_pair(index: int, stance: int, move: StringName, stance_pose: bool) -> Dictionary:
	var origin := Vector3(3.0 * index, 0, 0)
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	character.position = origin
	root.add_child(character)
	var lead_is_left := stance == PunchController.ORTHODOX
	var left := lead_is_left == (move in [&"jab", &"lead_hook", &"lead_uppercut"])
	var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	var offset := PunchSpec.default_target_offset()
	offset.x = SIDE_M if left else -SIDE_M  # +X is the character's left
	sandbag.position = origin + offset
	root.add_child(sandbag)
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.set("character", character)
	controller.set("target", sandbag.get_node("Bag"))
	controller.set("stance", stance)
	controller.set("stance_pose", stance_pose)
	root.add_child(controller)
	# The bag at the middle of the move's reach (a lead hand's in the stance lies further ahead: docs/moves.md).
	var distance: Vector2 = controller.call("reach_volume", move).distance_m
	offset.z = (distance.x + distance.y) / 2.0
	sandbag.position = origin + offset
	var entry := {"stance": stance, "move": String(move), "stance_pose": stance_pose, "bag_side_m": offset.x,
		"started": [], "hits": [], "finished": []}
	controller.connect("punch_started", func(move_name, hand, _combo_index): entry.started.append([String(move_name), String(hand)]))
	controller.connect("hit", func(_impulse, speed, position, body, _push, hand, _part, _blocked):
		entry.hits.append({"hand": String(hand), "speed": speed, "x": position.x - origin.x, "bag": body == sandbag.get_node("Bag")}))
	controller.connect("punch_finished", func(metrics): entry.finished.append(metrics))
	return {"controller": controller, "entry": entry, "move": move}


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:  # with stance_pose, each punch returns to the stance's guard first (`guard_first`)
		for throw in _throws:
			throw.controller.call("punch", throw.move)
		_refusals()
	if _throws.all(func(throw): return throw.entry.finished.size() == 1) or _frames > 900:
		_report.throws = _throws.map(func(throw): return throw.entry)
		print("MOVES_SCENE ", JSON.stringify(_report))
		quit(0)
	return false


## What a game gets wrong, each answered by `punch()` returning false (the log says why).
func _refusals() -> void:
	var controller: Node = _throws[0].controller
	var other: Node = ClassDB.instantiate("PunchController")
	other.set("character", controller.get("character"))
	other.set("target", controller.get("target"))
	root.add_child(other)
	_report.reach_of_jab = other.call("reach_volume", &"jab")
	_report.reach_of_haymaker = other.call("reach_volume", &"haymaker")
	# No moveset set: the addon's, the stance's with `stance_pose` (its lead hook's volume lies further ahead).
	var distance: Vector2 = other.call("reach_volume", &"lead_hook").distance_m
	_report.lead_hook_distance_m = [distance.x, distance.y]
	other.set("stance_pose", true)
	distance = other.call("reach_volume", &"lead_hook").distance_m
	_report.lead_hook_in_stance_distance_m = [distance.x, distance.y]
	other.set("stance_pose", false)
	_report.refused["haymaker"] = other.call("punch", &"haymaker")
	var moveset: Resource = ClassDB.instantiate("PunchMoveset")
	moveset.set("jab", load("res://addons/punch_controller/policies/straight.onnx"))
	other.set("moveset", moveset)
	_report.refused["cross_from_own_moveset"] = other.call("punch", &"cross")
	_report.moves_of_own_moveset = Array(moveset.call("moves"))
	_report.moves_of_addon_moveset = Array(load("res://addons/punch_controller/policies/boxing.tres").call("moves"))
	other.queue_free()
