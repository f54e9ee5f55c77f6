## Plays the moving duel demo (godot_project/demo/moving_duel.tscn) for `--seconds=N` of physics time and
## measures it from outside, as a spectator would: per side how far its mover and its simulated pelvis went and
## turned (the pelvis read from the physics server), its punches and by which policy, those that struck the
## opponent and those on its trunk, and its targets out of reach. Pass `--autoplay` for the demo to play both
## sides. Prints `MOVING_DUEL <json>` and quits.
extends SceneTree

var _duel: Node
var _frames := 0
var _frames_wanted := 0
var _sides := {}


func _initialize() -> void:
	var seconds := 10.0
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		if parts[0] == "seconds" and parts.size() == 2:
			seconds = float(parts[1])
	_frames_wanted = roundi(seconds * Engine.physics_ticks_per_second)
	_duel = load("res://demo/moving_duel.tscn").instantiate()
	root.add_child(_duel)


## Watches each side once the demo has made its fighters (in its _ready).
func _watch() -> void:
	for fighter in _duel._fighters:
		var side := {"path_m": 0.0, "turned_rad": 0.0, "pelvis_path_m": 0.0, "pelvis_turned_rad": 0.0,
			"out_of_reach": 0, "by_style": {}, "last": null}
		_sides[fighter.name] = side
		fighter.controller.target_out_of_reach.connect(func(_offset, _nearest): side.out_of_reach += 1)
		fighter.controller.punch_started.connect(func(_move, _hand, _combo_index):
			side.by_style[fighter.style] = side.by_style.get(fighter.style, 0) + 1)


func _physics_process(_delta: float) -> bool:
	if _sides.is_empty():
		_watch()
	_frames += 1
	for fighter in _duel._fighters:
		_measure(fighter, _sides[fighter.name])
	if _frames < _frames_wanted:
		return false
	var report := {}
	for fighter in _duel._fighters:
		var side: Dictionary = _sides[fighter.name]
		side.erase("last")
		side.merge({"punches": fighter.punches, "hits": fighter.hits, "hits_on_body": fighter.hits_on_body})
		report[fighter.name] = side
	print("MOVING_DUEL ", JSON.stringify({"seconds": float(_frames) / Engine.physics_ticks_per_second,
		"policies": _duel._policies.keys(), "sides": report}))
	quit(0)
	return false


## Adds how far the mover and the simulated pelvis went and turned since the last frame.
func _measure(fighter, side: Dictionary) -> void:
	var pelvis_body: PhysicsBody3D = fighter.character.get_node("Pelvis")
	var now := {"position": fighter.mover.global_position, "yaw": fighter.mover.rotation.y,
		"pelvis": PhysicsServer3D.body_get_state(pelvis_body.get_rid(), PhysicsServer3D.BODY_STATE_TRANSFORM)}
	var last = side.last
	if last != null:
		side.path_m += now.position.distance_to(last.position)
		side.turned_rad += absf(angle_difference(last.yaw, now.yaw))
		side.pelvis_path_m += now.pelvis.origin.distance_to(last.pelvis.origin)
		side.pelvis_turned_rad += last.pelvis.basis.get_rotation_quaternion().angle_to(now.pelvis.basis.get_rotation_quaternion())
	side.last = now
