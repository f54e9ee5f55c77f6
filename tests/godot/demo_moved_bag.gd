## The demo played as a designer would with the bag moved: the demo scene, "repeat" off, and after each punch
## the "Move bag" action (a random spot of the policy's reach volume). Prints `DEMO_MOVED <json>` with the
## punches, how many hit, the placements and the demo's hit-rate label, and quits.
## Args: [--punches=N] (default 20)
extends SceneTree

var _demo: Node
var _punches := 20
var _report := {"punches": 0, "hit": 0, "placements": [], "out_of_reach": 0}


func _initialize() -> void:
	for argument in OS.get_cmdline_user_args():
		if argument.begins_with("--punches="):
			_punches = int(argument.get_slice("=", 1))
	_demo = load("res://demo/demo.tscn").instantiate()
	root.add_child(_demo)
	(_demo.get_node("%Repeat") as CheckBox).button_pressed = false
	var controller: Node = _demo.get_node("PunchController")
	controller.punch_finished.connect(_on_finished)
	controller.target_out_of_reach.connect(func(_offset, _nearest): _report.out_of_reach += 1)


func _on_finished(metrics: Dictionary) -> void:
	if metrics.interrupted:
		return  # the demo's first punch, interrupted by the first move
	_report.punches += 1
	if metrics.hits > 0:
		_report.hit += 1
	_report.placements.append((_demo.get_node("%Placement") as Label).text)
	if _report.punches >= _punches:
		_report["hit_rate_label"] = (_demo.get_node("%HitRate") as Label).text
		print("DEMO_MOVED ", JSON.stringify(_report))
		quit()
		return
	_demo.call_deferred("move_bag_to_random_spot")
