@tool
## The physics settings the punching policies are trained with (`PunchSpec.required_project_settings()`),
## checked and applied to the open project. Used by the editor plugin; a build script may call it too.
extends RefCounted


## One line per setting this project has wrong, saying what to set (empty when all is well).
static func problems() -> PackedStringArray:
	return ClassDB.class_call_static("PunchSpec", "project_settings_problems")


## Sets every required setting and saves project.godot. Returns the paths it changed. A change of physics
## engine takes effect when the project is next started.
static func apply() -> PackedStringArray:
	var changed := PackedStringArray()
	var required: Dictionary = ClassDB.class_call_static("PunchSpec", "required_project_settings")
	for path in required:
		var value = required[path]
		var current = ProjectSettings.get_setting(path)
		var same: bool = is_equal_approx(current, value) if value is float and current is float else current == value
		if not same:
			ProjectSettings.set_setting(path, value)
			changed.append(path)
	if not changed.is_empty():
		ProjectSettings.save()
	return changed
