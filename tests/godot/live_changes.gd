## Punch after punch and live changes, each on its own character and sandbag (demo policies):
## - "ready" and "ready_twin": punch() called from the controller's `ready` signal (as a game's _ready
##   would), on two characters in the same state: the same punch;
## - "switch": the policy changed to the hook mid-punch (frame 10): the punch plays on to its end with the
##   straight, and the next punch (asked for when it ends) plays the hook; the first decision's mean action of
##   each punch;
## - "cancel": cancel() on frame 5; "recover": auto_recover off, recover() called after the punch;
## - "seeds": sigma 0.3, punches with seed 1, 2, then 1 again: the first decision's noise of each;
## - "again" and "again_raw": a second punch asked for as the first ends (guard_first on, and off): the first
##   frame's joint angles and the hits of each punch (the bag is put back still before the second); these two
##   characters are turned (90 and -150 degrees).
## Prints `LIVE_CHANGES <json>` and quits.
extends SceneTree

const STRAIGHT := "res://addons/punch_controller/policies/straight.onnx"
const HOOK := "res://addons/punch_controller/policies/hook.onnx"
const CASES := ["ready", "ready_twin", "switch", "cancel", "recover", "seeds", "again", "again_raw"]
# The joint angles' first feature column, by name from the controller itself.
var _angle_column: int = Array(PunchSpec.feature_names()).find("angle_waist_flexion")
var _controllers := {}
var _report := {}
var _frames := 0
var _seeds := [1, 2, 1]
var _bag_starts := {}


func _initialize() -> void:
	for index in CASES.size():
		var name: String = CASES[index]
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.position = Vector3(4.0 * index, 0, 0)
		if name.begins_with("again"):
			character.rotation.y = deg_to_rad(90.0 if name == "again" else -150.0)  # turned, not at the origin
		root.add_child(character)
		var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
		sandbag.position = character.transform * PunchSpec.default_target_offset()
		root.add_child(sandbag)
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", sandbag.get_node("Bag"))
		_bag_starts[name] = sandbag.transform * sandbag.get_node("Bag").transform
		controller.set("policy", load(STRAIGHT))
		PunchProbe.set_recording(controller, true)
		if name == "recover":
			controller.set("auto_recover", false)
		if name == "again_raw":
			controller.set("guard_first", false)
		if name == "seeds":
			controller.set("noise_sigma", 0.3)
			controller.set("noise_decisions", 1)
		_report[name] = {"finished": [], "recovered": 0, "started": 0, "first_noise": [], "features": [],
			"first_angles": [], "first_means": []}
		controller.connect("punch_started", func(_move, _hand, _combo_index): _report[name].started += 1)
		controller.connect("punch_finished", func(metrics): _on_finished(name, controller, metrics))
		controller.connect("recovered", func(): _on_recovered(name, controller))
		if name.begins_with("ready"):
			controller.ready.connect(func(): _report[name]["punch_in_ready"] = controller.call("punch"))
		root.add_child(controller)
		_controllers[name] = controller


func _on_finished(name: String, controller: Node, metrics: Dictionary) -> void:
	_report[name].finished.append(metrics)
	var record: Dictionary = PunchProbe.last_punch_record(controller)
	if name.begins_with("ready"):
		_report[name].features = Array(record.features)
	if name.begins_with("again"):
		_report[name].first_angles.append(Array(record.features.slice(_angle_column, _angle_column + 10)))
		if _report[name].finished.size() == 1:
			# The bag hangs still again (as in `punch eval`'s "after a punch"): only the arms' pose differs.
			var bag: RigidBody3D = controller.get("target")
			bag.global_transform = _bag_starts[name]
			bag.linear_velocity = Vector3.ZERO
			bag.angular_velocity = Vector3.ZERO
			controller.call("punch")
	if name == "seeds" and record.decisions > 0:
		var noise := []
		for i in 10:
			noise.append(record.actions[i] - record.mean_actions[i])
		_report[name].first_noise.append(noise)
	if name == "recover" and not metrics.interrupted:
		controller.call("recover")
	if name == "switch":
		_report[name].first_means.append(Array(record.mean_actions.slice(0, 10)))
		if _report[name].finished.size() == 1:
			controller.call("punch")


func _on_recovered(name: String, controller: Node) -> void:
	_report[name].recovered += 1
	if name == "seeds" and not _seeds.is_empty():
		controller.set("seed", _seeds.pop_front())
		controller.call("punch")


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		for name in ["switch", "cancel", "recover", "seeds", "again", "again_raw"]:
			_controllers[name].call("punch")
	if _frames == 5:
		_controllers["cancel"].call("cancel")
		_report["cancel"]["punching_after_cancel"] = _controllers["cancel"].call("is_punching")
	if _frames == 10:
		_controllers["switch"].set("policy", load(HOOK))
		_report["switch"]["punching_after_switch"] = _controllers["switch"].call("is_punching")
	if _frames > 600:
		for name in CASES:
			_report[name]["recovering"] = _controllers[name].call("is_recovering")
		print("LIVE_CHANGES ", JSON.stringify(_report))
		quit(0)
	return false
