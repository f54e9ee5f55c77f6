## A game scene as a user would build it: the addon's character and sandbag, and a PunchController with a
## trained policy (--policy=PATH) and no noise. Prints `PUNCH_SCENE <json>` with the signals seen, then quits.
## Also checks that a missing or incompatible policy makes punch() refuse without crashing.
extends SceneTree

var _controller: Node
var _report := {"started": 0, "hits": [], "finished": null, "missing_policy_refused": false, "incompatible_refused": false}
var _frames := 0


func _initialize() -> void:
	var policy := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			policy = argument.trim_prefix("--policy=")
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	root.add_child(character)
	var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	sandbag.position = Vector3(0, 1.35, 0.72)
	root.add_child(sandbag)
	_controller = ClassDB.instantiate("PunchController")
	_controller.set("character", character)
	_controller.set("target", sandbag.get_node("Bag"))
	root.add_child(_controller)
	_controller.connect("punch_started", func(): _report.started += 1)
	_controller.connect("hit", func(impulse, speed, position): _report.hits.append([impulse, speed]))
	_controller.connect("punch_finished", func(metrics): _report.finished = metrics)

	# Bad policies first: each is refused with an error in the log, and nothing crashes.
	_controller.set("policy", "res://no/such/policy.onnx")
	_report.missing_policy_refused = not _controller.call("punch")
	var fixture: String = get_script().resource_path.get_base_dir().path_join("../fixtures/tiny_actor.onnx").simplify_path()
	var incompatible: Node = ClassDB.instantiate("PunchController")
	incompatible.set("character", character)
	incompatible.set("target", sandbag.get_node("Bag"))
	incompatible.set("policy", fixture)
	root.add_child(incompatible)
	_report.incompatible_refused = not incompatible.call("punch")

	_controller.set("policy", policy)


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		_controller.call("punch")
	if _report.finished != null or _frames > 400:
		print("PUNCH_SCENE ", JSON.stringify(_report))
		quit(0)
	return false
