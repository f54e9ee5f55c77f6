## Stack self-check, started by `punch selfcheck`: proves that this Godot runs Jolt Physics, loads the
## punch controller extension, and runs an ONNX model through it. Prints one line
## `PUNCH_SELFCHECK <json>` and exits 0, or prints the problems and exits 1.
## Arguments (after `--`): --model=ABSOLUTE_PATH.onnx --input=ABSOLUTE_PATH.json ({"batch": B, "values": [...]}).
extends SceneTree

## Speed given to a free probe body. Jolt clamps body speeds to its max_linear_velocity setting (500 m/s by
## default) and Godot Physics does not, so the probe's speed after a step tells which engine is active.
const PROBE_SPEED_MPS := 1000.0
const JOLT_SPEED_LIMIT_SETTING := "physics/jolt_physics_3d/limits/max_linear_velocity"

var _arguments := {}
var _probe: RigidBody3D
var _physics_frames := 0


func _initialize() -> void:
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		_arguments[parts[0]] = parts[1] if parts.size() > 1 else ""
	_probe = RigidBody3D.new()
	_probe.gravity_scale = 0.0
	_probe.linear_damp_mode = RigidBody3D.DAMP_MODE_REPLACE
	_probe.linear_damp = 0.0
	var shape := CollisionShape3D.new()
	shape.shape = SphereShape3D.new()
	_probe.add_child(shape)
	root.add_child(_probe)
	_probe.linear_velocity = Vector3(PROBE_SPEED_MPS, 0.0, 0.0)


func _physics_process(_delta: float) -> bool:
	_physics_frames += 1
	if _physics_frames == 3:
		var problems: Array[String] = []
		var report := {
			"godot": Engine.get_version_info().string,
			"physics": _physics_report(problems),
			"extension": _extension_report(problems),
		}
		if report.extension.loaded:
			report["model"] = _run_model(problems)
		report["problems"] = problems
		print("PUNCH_SELFCHECK ", JSON.stringify(report, "", true, true))
		for problem in problems:
			printerr("selfcheck: ", problem)
		quit(0 if problems.is_empty() else 1)
	return false


func _physics_report(problems: Array[String]) -> Dictionary:
	var setting: String = ProjectSettings.get_setting("physics/3d/physics_engine")
	var speed_after_step := _probe.linear_velocity.length()
	var jolt_limit: float = ProjectSettings.get_setting(JOLT_SPEED_LIMIT_SETTING, -1.0)
	var clamped_by_jolt := jolt_limit > 0.0 and absf(speed_after_step - jolt_limit) < 1e-3 * jolt_limit
	if setting != "Jolt Physics":
		problems.append("project setting physics/3d/physics_engine is '%s', not 'Jolt Physics'" % setting)
	if not clamped_by_jolt:
		problems.append("the active 3D physics server is not Jolt: a %.0f m/s body kept %.1f m/s" % [PROBE_SPEED_MPS, speed_after_step])
	return {
		"engine": "Jolt Physics" if clamped_by_jolt else "not Jolt",
		"setting": setting,
		"probe_speed_mps": speed_after_step,
		"ticks_per_second": Engine.physics_ticks_per_second,
	}


func _extension_report(problems: Array[String]) -> Dictionary:
	if not ClassDB.class_exists("PunchRuntime"):
		problems.append("the punch controller extension is not loaded (class PunchRuntime missing)")
		return {"loaded": false}
	var versions: Dictionary = ClassDB.class_call_static("PunchRuntime", "versions")
	if not versions.onnxruntime_loaded:
		problems.append("the extension could not load ONNX Runtime (see the error above)")
	versions["loaded"] = true
	return versions


func _run_model(problems: Array[String]) -> Dictionary:
	if not _arguments.has("model") or not _arguments.has("input"):
		return {"skipped": "no --model/--input given"}
	var request = JSON.parse_string(FileAccess.get_file_as_string(_arguments.input))
	if request == null:
		problems.append("could not read the input file %s" % _arguments.input)
		return {}
	var policy: RefCounted = ClassDB.instantiate("PunchPolicy")
	if policy.load(_arguments.model) != OK:
		problems.append("PunchPolicy could not load %s" % _arguments.model)
		return {}
	var outputs: Dictionary = policy.run(PackedFloat32Array(request["values"]), int(request["batch"]))
	if outputs.is_empty():
		problems.append("PunchPolicy.run returned nothing")
	var result := {"input_width": policy.get_input_width(), "outputs": {}}
	for output_name in outputs:
		result.outputs[output_name] = Array(outputs[output_name])
	return result
