## How near its guard a combination's next punch starts (`PunchMoveset`'s "Returns to guard"): two characters, each
## with its own sandbag and a copy of the addon's moveset, throw the same `combo([&"cross", &"lead_uppercut"])`; one
## with the moveset's default tolerance for the uppercut (settled), the other with 0.3 rad. For each: the frames from
## the uppercut's `punch_started` (its cancel window) to its fist's first hit, and whether it landed. Also the
## addon moveset's default tolerances by move. Prints `GUARD_TOLERANCE <json>` and quits.
extends SceneTree

const MOVESET := "res://addons/punch_controller/policies/boxing.tres"
const CASES := {"default": -1.0, "wide": 0.3}
var _frame := 0
var _report := {"defaults": {}}


func _initialize() -> void:
	var addon: Resource = load(MOVESET)
	for move in addon.call("moves"):
		_report.defaults[move] = addon.get("%s_guard_tolerance_rad" % move)
	var index := 0
	for name in CASES:
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.position = Vector3(4.0 * index, 0, 0)
		root.add_child(character)
		var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
		sandbag.position = character.transform * PunchSpec.default_target_offset()
		root.add_child(sandbag)
		var moveset: Resource = addon.duplicate()
		if CASES[name] >= 0.0:
			moveset.set("lead_uppercut_guard_tolerance_rad", CASES[name])
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", sandbag.get_node("Bag"))
		controller.set("moveset", moveset)
		root.add_child(controller)
		_report[name] = {"started": [], "hits": [], "finished": []}
		controller.connect("punch_started", func(move, _hand, _index): _report[name].started.append([move, _frame]))
		controller.connect("hit", func(_impulse, _speed, _position, _body, _push, hand, _part, _blocked):
			_report[name].hits.append([hand, _frame]))
		controller.connect("punch_finished", func(metrics): _report[name].finished.append(metrics.outcome))
		index += 1


func _physics_process(_delta: float) -> bool:
	_frame += 1
	if _frame == 5:
		for controller in root.get_children().filter(func(n): return n.get_class() == "PunchController"):
			controller.call("combo", [&"cross", &"lead_uppercut"])
	if _frame == 240:
		print("GUARD_TOLERANCE ", JSON.stringify(_report))
		quit(0)
	return false
