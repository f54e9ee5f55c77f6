## Faults a game can throw at PunchController, one after another in one running game: bad policy files, a
## policy that outputs NaN, the target or the character freed mid-punch, out-of-range sigma from code, and a
## policy loaded from inside a .pck. Each must give its clear error (or a clamp) and the game must go on.
## Args: --policy=GOOD.onnx --nan-policy=NAN.onnx --corrupt=FILE --tiny=TINY.onnx --pck=OUT.pck
## [--incomplete=POLICY.onnx: a policy whose metadata lacks a key of the contract]
## Prints `FAULTS <json>` and quits 0.
extends SceneTree

var _args := {}
var _report := {}
var _steps: Array[Callable] = []
var _wait := 0
var _character: Node3D
var _sandbag: Node3D
var _controller: Node


func _initialize() -> void:
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		_args[parts[0]] = parts[1]
	_steps = [_bad_files, _nan_outputs, _freed_mid_punch.bind("target"), _freed_mid_punch.bind("character"),
		_sigma_clamped, _packed_policy]


func _physics_process(_delta: float) -> bool:
	if _wait > 0:
		_wait -= 1
		return false
	if _steps.is_empty():
		print("FAULTS ", JSON.stringify(_report))
		quit(0)
		return false
	_steps.pop_front().call()
	return false


func _scene() -> Node:
	for node in [_character, _sandbag, _controller]:
		if is_instance_valid(node):
			node.free()
	_character = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
	root.add_child(_character)
	_sandbag = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
	_sandbag.position = PunchSpec.default_target_offset()
	root.add_child(_sandbag)
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.set("character", _character)
	controller.set("target", _sandbag.get_node("Bag"))
	controller.set("policy", load(_args.policy))
	root.add_child(controller)
	_controller = controller
	return controller


func _bad_files() -> void:
	var controller := _scene()
	var refused := {}
	for case in [["missing", "res://no/such/policy.onnx"], ["corrupt", _args.corrupt], ["incompatible", _args.tiny], ["empty", ""]]:
		controller.set("policy", load(case[1]) if case[1] != "" else null)
		refused[case[0]] = not controller.call("punch")
	# A policy trained for another spec (its hash names another decision period or observation) is refused.
	controller.set("policy", load(_args["other-spec"]))
	refused["other_spec"] = not controller.call("punch")
	controller.set("policy", load(_args.policy))
	controller.set("decision_period", 4)  # read-only: it stays the policy's
	refused["decision_period_read_only"] = controller.get("decision_period") == 5
	# A mirrored character (a game's left-handed variant by scale.x = -1) cannot land: refused, saying why.
	_character.scale = Vector3(-1, 1, 1)
	refused["mirrored"] = not controller.call("punch")
	_character.scale = Vector3.ONE
	# ... and so is one mirrored by a parent, turned and moved as a game places it.
	var pivot := Node3D.new()
	root.add_child(pivot)
	_character.reparent(pivot, false)
	pivot.transform = Transform3D(Basis(Vector3.UP, 0.7).scaled(Vector3(1, 1, -1)), Vector3(2, 0, -1))
	refused["mirrored_by_parent"] = not controller.call("punch")
	_character.reparent(root, false)
	pivot.free()
	refused["good_policy_afterwards_punches"] = controller.call("punch")
	_report["refused"] = refused
	if _args.has("incomplete"):
		var incomplete := _scene()
		incomplete.set("policy", load(_args.incomplete))
		_report["incomplete_refused"] = not incomplete.call("punch")
	_wait = 5


func _nan_outputs() -> void:
	var controller := _scene()
	controller.set("policy", load(_args["nan-policy"]))
	controller.connect("punch_finished", func(metrics): _report["nan_finished"] = metrics)
	_report["nan_started"] = controller.call("punch")
	_steps.push_front(func(): _report["nan_stopped"] = not controller.call("is_punching"))
	_wait = 3


## Frees the sandbag ("target") or the character ten frames into a punch; the punch must stop by itself.
func _freed_mid_punch(what: String) -> void:
	var controller := _scene()
	controller.call("punch")
	_steps.push_front(func():
		(_sandbag if what == "target" else _character).free()
		_steps.push_front(func(): _report[what + "_freed_stopped"] = not controller.call("is_punching"))
		_wait = 2)
	_wait = 10


func _sigma_clamped() -> void:
	var controller := _scene()
	var seen := []
	for value in [5.0, -1.0, NAN, 0.25]:
		controller.set("noise_sigma", value)
		seen.append(controller.get("noise_sigma"))
	_report["sigma_after_set"] = seen


func _packed_policy() -> void:
	# An exported game reads its files from a .pck: pack the policy, mount it, and punch from res://.
	var packer := PCKPacker.new()
	packer.pck_start(_args.pck)
	packer.add_file("res://packed_policies/straight.onnx", _args.policy)
	packer.flush()
	_report["pck_mounted"] = ProjectSettings.load_resource_pack(_args.pck)
	var controller := _scene()
	controller.set("policy", load("res://packed_policies/straight.onnx"))
	controller.connect("punch_finished", func(metrics): _report["pck_punch"] = metrics)
	_report["pck_started"] = controller.call("punch")
	_wait = 60
