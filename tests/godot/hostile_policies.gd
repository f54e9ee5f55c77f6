## Policy files that lie about themselves, each played by three controllers at once (as a crowd sharing one
## file would): every one must be refused, at load or when a punch starts, with one error per file, and the game
## goes on.
## Args: --files=A.onnx,B.onnx,...  Prints `HOSTILE <json>` (file -> punch() results) and quits 0.
extends SceneTree


var _done := false


# In the first physics frame: nodes added in _initialize are not in the tree yet, and a controller outside the
# tree refuses to punch.
func _physics_process(_delta: float) -> bool:
	if _done:
		return false
	_done = true
	var files := PackedStringArray()
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--files="):
			files = argument.trim_prefix("--files=").split(",")
	var report := {}
	for file in files:
		var results := []
		var policy: Resource = load(file)  # null when the file is refused at load
		for i in 3:
			var controller: Node = ClassDB.instantiate("PunchController")
			controller.set("policy", policy)
			root.add_child(controller)
			results.append(controller.call("punch"))
		report[file] = results
	print("HOSTILE ", JSON.stringify(report))
	quit(0)
	return false
