@tool
class_name PunchPolicyLoader
extends ResourceFormatLoader
## Loads policy files (.onnx, from `punch train`) as PunchPolicy resources: the editor lists them,
## PunchController.policy takes them, and an export packs them like any resource a scene uses. Godot
## registers this loader by itself (a global class that extends ResourceFormatLoader), in the editor and in
## exported games. GDScript, not the extension: the editor asks loaders about files from its scanning
## thread, and the extension's code runs on the main thread only.


func _get_recognized_extensions() -> PackedStringArray:
	return PackedStringArray(["onnx"])


func _handles_type(type: StringName) -> bool:
	return type == &"PunchPolicy" or type == &"Resource"


func _get_resource_type(path: String) -> String:
	return "PunchPolicy" if path.get_extension().to_lower() == "onnx" else ""


func _load(path: String, _original_path: String, _use_sub_threads: bool, _cache_mode: int) -> Variant:
	if not ClassDB.class_exists("PunchPolicy"):
		push_error("PunchPolicy '%s': the punch controller extension is not loaded" % path)
		return ERR_UNAVAILABLE
	if OS.get_thread_caller_id() != OS.get_main_thread_id():
		push_error("PunchPolicy '%s': policies load on the main thread only (not with load_threaded_request)" % path)
		return ERR_UNAVAILABLE
	var policy: Resource = ClassDB.instantiate("PunchPolicy")
	var error: Error = policy.call("load", path)
	return policy if error == OK else error
