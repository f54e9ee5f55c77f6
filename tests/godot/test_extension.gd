## Headless test of the extension's Godot surface: its classes, versions, a model loaded from bytes that
## matches Python's onnxruntime, and clear errors (never a crash) for missing or garbage models and bad input.
## Run inside godot_project by tests/python/test_godot_scripts.py; exits 1 when any check fails.
extends SceneTree

const TOLERANCE := 1e-5

var _failures: Array[String] = []
var _fixtures_dir: String


func _initialize() -> void:
	_fixtures_dir = get_script().resource_path.get_base_dir().path_join("../fixtures").simplify_path()
	_test_classes_are_registered()
	_test_versions()
	_test_fixture_matches_python()
	_test_missing_model_is_an_error()
	_test_garbage_model_is_an_error()
	_test_bad_input_is_an_error()
	for failure in _failures:
		printerr("FAILED: ", failure)
	print("test_extension: %s" % ("ok" if _failures.is_empty() else "%d failure(s)" % _failures.size()))
	quit(0 if _failures.is_empty() else 1)


func _check(condition: bool, message: String) -> void:
	if not condition:
		_failures.append(message)


func _test_classes_are_registered() -> void:
	for name in ["PunchPolicy", "PunchRuntime"]:
		_check(ClassDB.class_exists(name), "class %s is registered" % name)


func _test_versions() -> void:
	var versions: Dictionary = ClassDB.class_call_static("PunchRuntime", "versions")
	_check(versions.get("onnxruntime_loaded", false), "ONNX Runtime loaded: %s" % versions)
	_check(String(versions.get("onnxruntime", "")).begins_with("1."), "ONNX Runtime version: %s" % versions)
	_check(String(versions.get("onnxruntime_library", "")).begins_with("/"), "library path is absolute")
	_check(String(versions.get("extension", "")) != "", "extension version present")


func _test_fixture_matches_python() -> void:
	var expected: Dictionary = JSON.parse_string(FileAccess.get_file_as_string(_fixtures_dir.path_join("tiny_actor_expected.json")))
	var policy: RefCounted = ClassDB.instantiate("PunchPolicy")
	# Bytes, as an exported game would read them from its .pck.
	var bytes := FileAccess.get_file_as_bytes(_fixtures_dir.path_join("tiny_actor.onnx"))
	_check(policy.load_from_bytes(bytes) == OK, "fixture loads from bytes")
	_check(policy.is_loaded(), "policy reports loaded")
	_check(policy.get_input_width() == int(expected.input_width), "input width")
	_check(Array(policy.get_output_names()) == ["mean", "sigma"], "output names")
	_check(policy.get_metadata("purpose") == expected.metadata.purpose, "metadata")
	var outputs: Dictionary = policy.run(PackedFloat32Array(expected.input), int(expected.batch))
	for output_name in expected.outputs:
		var want: Array = expected.outputs[output_name]
		var got: PackedFloat32Array = outputs.get(output_name, PackedFloat32Array())
		_check(got.size() == want.size(), "output %s size %d == %d" % [output_name, got.size(), want.size()])
		var worst := 0.0
		for i in mini(got.size(), want.size()):
			worst = maxf(worst, absf(got[i] - float(want[i])))
		_check(worst <= TOLERANCE, "output %s differs from Python by %g" % [output_name, worst])


func _test_missing_model_is_an_error() -> void:
	var policy: RefCounted = ClassDB.instantiate("PunchPolicy")
	_check(policy.load("res://no/such/model.onnx") == ERR_FILE_NOT_FOUND, "missing file -> ERR_FILE_NOT_FOUND")
	_check(not policy.is_loaded(), "nothing loaded after a missing file")


func _test_garbage_model_is_an_error() -> void:
	var policy: RefCounted = ClassDB.instantiate("PunchPolicy")
	_check(policy.load_from_bytes("not an onnx model".to_utf8_buffer()) == ERR_INVALID_DATA, "garbage -> ERR_INVALID_DATA")
	_check(policy.load_from_bytes(PackedByteArray()) == ERR_INVALID_DATA, "empty -> ERR_INVALID_DATA")
	_check(not policy.is_loaded(), "nothing loaded after garbage")
	_check(policy.run(PackedFloat32Array([1.0]), 1).is_empty(), "run without a model returns nothing")


func _test_bad_input_is_an_error() -> void:
	var policy: RefCounted = ClassDB.instantiate("PunchPolicy")
	policy.load_from_bytes(FileAccess.get_file_as_bytes(_fixtures_dir.path_join("tiny_actor.onnx")))
	var width: int = policy.get_input_width()
	var wrong_size := PackedFloat32Array()
	wrong_size.resize(width + 1)
	_check(policy.run(wrong_size, 1).is_empty(), "wrong input size returns nothing")
	var with_nan := PackedFloat32Array()
	with_nan.resize(width)
	with_nan[0] = NAN
	_check(policy.run(with_nan, 1).is_empty(), "NaN input returns nothing")
	_check(policy.run(PackedFloat32Array(), -3).is_empty(), "negative batch returns nothing")
	# The policy still works after bad calls.
	var zeros := PackedFloat32Array()
	zeros.resize(width)
	_check(not policy.run(zeros, 1).is_empty(), "policy still runs after bad input")
