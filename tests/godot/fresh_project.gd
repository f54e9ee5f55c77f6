## Run in a new Godot project that holds only the addon and a policy (--policy=PATH): a character, a sandbag in
## front of it and a PunchController, wired by hand. Prints `FRESH_PROJECT <json>`: the settings problems the
## controller finds, whether punch() started (twice: the second follows the first at its contact; the settings
## error is logged once), and every `punch_finished`. With --apply it first sets the physics
## settings the way the editor plugin does (and saves project.godot).
extends SceneTree

var _report := {}
var _controller: Node
var _frames := 0


func _initialize() -> void:
	var policy := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			policy = argument.trim_prefix("--policy=")
		if argument == "--apply":
			_report["applied"] = load("res://addons/punch_controller/physics_settings.gd").apply()
	_report["problems"] = PunchSpec.project_settings_problems()
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	root.add_child(character)
	var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	sandbag.position = PunchSpec.default_target_offset()
	root.add_child(sandbag)
	_controller = ClassDB.instantiate("PunchController")
	_controller.set("character", character)
	_controller.set("target", sandbag.get_node("Bag"))
	_controller.set("policy", load(policy))
	root.add_child(_controller)
	_report["finished"] = []
	_controller.connect("punch_finished", func(metrics): _report.finished.append(metrics))


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 1:
		_report["started"] = _controller.call("punch")
		_report["started_again"] = _controller.call("punch")
	if _report.finished.any(func(metrics): return not metrics.interrupted) or _frames > 200:
		print("FRESH_PROJECT ", JSON.stringify(_report))
		quit(0)
	return false
