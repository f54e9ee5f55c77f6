## Whatever a game's signal handlers do, every `punch_started` is followed by exactly one `punch_finished`, and a
## punch in one controller never affects another's. Each case is its own character, sandbag and controller
## under one holder node, all punching the shipped straight policy from frame 2; the handlers:
## - "free_other_in_hit" / "free_other_in_finished": free() another case's holder (its controller punching)
##   inside `hit` / `punch_finished` (its victims: "victim_hit", "victim_finished");
## - "free_self_in_hit": free() its own holder (controller, character and sandbag) inside `hit`;
## - "free_character_in_hit" / "free_target_in_hit": free() only its character / its target's sandbag;
## - "removed_in_hit": remove_child() of the controller inside `hit`, then queue_free() of it inside its
##   `punch_finished`;
## - "same_policy_every_frame": `policy = policy` every frame; "new_policy_in_started": the hook set in
##   `punch_started` (this punch plays on with the straight, the next one plays the hook);
## - "sigma_seed_in_hit": noise_sigma set to INF, then 1e30, and a new seed, inside `hit`;
## - "punch_in_hit": punch() again inside the first `hit`; "punch_in_started": punch() again inside the first
##   `punch_started`;
## - "outside_tree": a controller never added to the tree; "taken_over" and "taker": two controllers on one
##   character, the second punching at frame 12;
## - "bystander": nothing; it must punch exactly as "bystander_alone", a run with no other case (--alone).
## Prints `HANDLERS <json>` (per case: its events, "S" started, "H" hit, "F:<ended>" finished, and more) and quits.
extends SceneTree

const STRAIGHT := "res://addons/punch_controller/policies/straight.onnx"
const HOOK := "res://addons/punch_controller/policies/hook.onnx"
const CASES := ["free_other_in_hit", "victim_hit", "free_other_in_finished", "victim_finished",
	"free_self_in_hit", "free_character_in_hit", "free_target_in_hit", "removed_in_hit", "same_policy_every_frame",
	"new_policy_in_started", "sigma_seed_in_hit", "punch_in_hit", "punch_in_started", "taken_over", "bystander"]

var _holders := {}
var _controllers := {}
var _report := {}
var _frames := 0


func _initialize() -> void:
	var alone := "--alone" in OS.get_cmdline_user_args()
	for index in CASES.size():
		var name: String = CASES[index]
		if alone and name != "bystander":
			continue
		_report[name] = {"events": [], "punch_returned": [], "sigma": [], "first_means": []}
		_add_case(name, index)
	if not alone:
		# A second controller on the "taken_over" case's character.
		var taker: Node = _controller_for("taker", _holders["taken_over"].get_node("Character"),
			_holders["taken_over"].get_node("Sandbag/Bag"))
		_holders["taken_over"].add_child(taker)
		# A controller that is not in the scene tree.
		_report["outside_tree"] = {"events": [], "punch_returned": []}
		var outside: Node = _controller_for("outside_tree", _holders["bystander"].get_node("Character"),
			_holders["bystander"].get_node("Sandbag/Bag"))
		_report["outside_tree"].punch_returned.append(outside.call("punch"))
		outside.free()


func _add_case(name: String, index: int) -> void:
	var holder := Node3D.new()
	holder.name = name
	holder.position = Vector3(4.0 * index, 0, 0)
	root.add_child(holder)
	var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	character.name = "Character"
	holder.add_child(character)
	var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	sandbag.name = "Sandbag"
	sandbag.position = PunchSpec.default_target_offset()
	holder.add_child(sandbag)
	holder.add_child(_controller_for(name, character, sandbag.get_node("Bag")))
	_holders[name] = holder


func _controller_for(name: String, character: Node3D, target: Node3D) -> Node:
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.name = "Controller_" + name
	controller.set("character", character)
	controller.set("target", target)
	controller.set("policy", load(STRAIGHT))
	PunchProbe.set_recording(controller, true)
	controller.set("auto_recover", false)
	_controllers[name] = controller
	if not _report.has(name):
		_report[name] = {"events": [], "punch_returned": [], "sigma": [], "first_means": []}
	controller.connect("punch_started", func(_move, _hand, _combo_index): _on_started(name, controller))
	controller.connect("hit", func(_impulse, _speed, _position, _body, _push, _hand, _part, _blocked): _on_hit(name, controller))
	controller.connect("punch_finished", func(metrics): _on_finished(name, controller, metrics))
	return controller


func _events(name: String) -> Array:
	return _report[name].events


func _on_started(name: String, controller: Node) -> void:
	_events(name).append("S")
	if name == "new_policy_in_started" and _events(name).count("S") == 1:
		controller.set("policy", load(HOOK))
	if name == "punch_in_started" and _events(name).count("S") == 1:
		_report[name].punch_returned.append(controller.call("punch"))


func _on_hit(name: String, controller: Node) -> void:
	_events(name).append("H")
	if _events(name).count("H") > 1:
		return
	match name:
		"free_other_in_hit":
			_free_holder("victim_hit")
		"free_self_in_hit":
			_free_holder(name)
		"free_character_in_hit":
			_holders[name].get_node("Character").free()
		"free_target_in_hit":
			_holders[name].get_node("Sandbag").free()
		"removed_in_hit":
			_holders[name].remove_child(controller)
		"sigma_seed_in_hit":
			for sigma in [INF, 1e30]:
				controller.set("noise_sigma", sigma)
				_report[name].sigma.append(controller.get("noise_sigma"))
			controller.set("seed", 5)
		"punch_in_hit":
			_report[name].punch_returned.append(controller.call("punch"))


func _on_finished(name: String, controller: Node, metrics: Dictionary) -> void:
	_events(name).append("F:" + metrics.ended)
	if name == "removed_in_hit":
		_report[name]["in_tree_when_finished"] = controller.is_inside_tree()
		controller.queue_free()  # (Godot refuses free() of an object emitting a signal)
		return
	if is_instance_valid(controller) and controller.is_inside_tree():
		var record: Dictionary = PunchProbe.last_punch_record(controller)
		if record.decisions > 0:
			_report[name].first_means.append(Array(record.mean_actions.slice(0, 10)))
	if name == "free_other_in_finished" and _events(name).count("F:completed") == 1:
		_free_holder("victim_finished")
	if name == "new_policy_in_started" and _events(name).count("F:completed") == 1:
		_report[name].punch_returned.append(controller.call("punch"))
	if name == "bystander" or name.begins_with("victim"):
		_report[name]["metrics"] = metrics


func _free_holder(name: String) -> void:
	if _holders.has(name) and is_instance_valid(_holders[name]):
		_report[name]["punching_when_freed"] = _controllers[name].call("is_punching")
		_holders[name].free()


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		for name in CASES:
			if _controllers.has(name) and is_instance_valid(_controllers[name]):
				_report[name].punch_returned.append(_controllers[name].call("punch"))
	if _frames == 12 and _controllers.has("taker"):
		_report["taker"].punch_returned.append(_controllers["taker"].call("punch"))
	if _controllers.has("same_policy_every_frame") and is_instance_valid(_controllers["same_policy_every_frame"]):
		var controller: Node = _controllers["same_policy_every_frame"]
		controller.set("policy", controller.get("policy"))
	if _frames > 200:
		print("HANDLERS ", JSON.stringify(_report))
		quit(0)
	return false
