## A game scene as a user would build it: the addon's character and sandbag, and a PunchController with a
## trained policy (--policy=PATH) and no noise; three such pairs, 3 m apart, sharing the policy, so their
## decisions run batched. Then all three punch again from their guard pose, and a few frames into that punch
## pair 1's `noise_sigma` is set to 0.8, as a designer dragging the inspector's slider while the game runs
## would. Prints `PUNCH_SCENE <json>` with the signals seen (each `punch_finished` with where the fist ended) and the
## first round's inference counts, then quits.
extends SceneTree

const PAIRS := 3
var _controllers: Array[Node] = []
var _report := {"started": 0, "hits": [], "finished": [], "inference": {}}
var _frames := 0
var _second_round_frame := -1


func _initialize() -> void:
	var policy := ""
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--policy="):
			policy = argument.trim_prefix("--policy=")
	for pair in PAIRS:
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.position = Vector3(3.0 * pair, 0, 0)
		root.add_child(character)
		var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
		sandbag.position = Vector3(3.0 * pair, 0, 0) + PunchSpec.default_target_offset()
		root.add_child(sandbag)
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", sandbag.get_node("Bag"))
		controller.set("policy", load(policy))
		root.add_child(controller)
		controller.connect("punch_started", func(_move, _hand, _combo_index): _report.started += 1)
		controller.connect("hit", func(impulse, speed, position, _body, _push, _hand, _part, _blocked): _report.hits.append([pair, impulse, speed, position.x]))
		controller.connect("punch_finished", func(metrics):
			metrics["pair"] = pair
			# Where the punching fist ended, in the character's frame (m): noise shows here even in a punch whose
			# peaks came before it and that struck nothing.
			var fist: Vector3 = character.global_transform.affine_inverse() * character.get_node("ForearmR/FistR").global_position
			metrics["fist_end"] = [fist.x, fist.y, fist.z]
			_report.finished.append(metrics))
		_controllers.append(controller)


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		PunchProbe.take_inference_counts()
		for controller in _controllers:
			controller.call("punch")
	if _report.finished.size() == PAIRS and _second_round_frame < 0:
		_report.inference = PunchProbe.take_inference_counts()
		_second_round_frame = _frames
		for pair in PAIRS:
			_controllers[pair].get("character").call("reset_pose")
			_controllers[pair].call("punch")
	if _second_round_frame > 0 and _frames == _second_round_frame + 6:
		_controllers[1].set("noise_sigma", 0.8)  # mid-punch, between decisions 1 and 2
	if _report.finished.size() == 2 * PAIRS or _frames > 600:
		print("PUNCH_SCENE ", JSON.stringify(_report))
		quit(0)
	return false
