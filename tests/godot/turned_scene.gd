## Characters facing every way: the addon's character turned by several yaw angles at several places, each with a sandbag in front of it (the spec's target offset, turned with it), all playing
## one policy (--policy=PATH) with no noise. Prints `TURNED_SCENE <json>`: per character its yaw, hits, peak
## fist speed and recorded features (frames x features, in the character's own frame), then quits.
extends SceneTree

## [yaw in degrees, position]
const POSES := [
	[0.0, Vector3(0, 0, 0)],
	[90.0, Vector3(5, 0, -3)],
	[-90.0, Vector3(-6, 0, 4)],
	[180.0, Vector3(12, 0, 12)],
	[37.0, Vector3(-20, 0, -15)],
	[-150.0, Vector3(30, 0, 0)],
]
var _controllers: Array[Node] = []
var _finished := {}
var _frames := 0


func _initialize() -> void:
	var policy := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			policy = argument.trim_prefix("--policy=")
	for index in POSES.size():
		var pose: Array = POSES[index]
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.transform = Transform3D(Basis(Vector3.UP, deg_to_rad(pose[0])), pose[1])
		root.add_child(character)
		var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
		# The target in front of the character: its offset in the character's frame, turned with it.
		sandbag.transform = Transform3D(character.transform.basis, character.transform * PunchSpec.default_target_offset())
		root.add_child(sandbag)
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", sandbag.get_node("Bag"))
		controller.set("policy", load(policy))
		PunchProbe.set_recording(controller, true)
		root.add_child(controller)
		controller.connect("punch_finished", func(metrics):
			var record: Dictionary = PunchProbe.last_punch_record(controller)
			_finished[index] = {"yaw": pose[0], "hits": metrics.hits, "peak_fist_speed_mps": metrics.peak_fist_speed_mps,
				"features": Array(record.features)})
		_controllers.append(controller)


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		for controller in _controllers:
			controller.call("punch")
	if _finished.size() == POSES.size() or _frames > 300:
		print("TURNED_SCENE ", JSON.stringify(_finished.values()))
		quit(0)
	return false
