## The moving duel demo played from the keyboard, as a player would: after a second of the autopilot, key
## events (Input.parse_input_event, as the OS would send them) hold W until the opponent is within reach and
## press Space, then hold D (circle to the right) with 2 (the hook) picked and Space again, then hold S. Between
## the keys the script reads the demo's fighters. Prints `MOVING_DUEL_KEYS <json>`, then quits.
## Arguments after `--`: --straight=PATH --hook=PATH --swing=PATH, passed on to the demo.
extends SceneTree

var _duel: Node
var _you: RefCounted
var _frames := 0
var _step := 0
var _step_frames := 0
var _report := {
	"driver_before": "", "driver_after": "", "closed_m": 0.0, "punches": [], "styles": [], "circled_rad": 0.0,
	"backed_m": 0.0, "facing_error_rad": 0.0, "hits": 0,
}
var _mark := {}


func _initialize() -> void:
	_duel = load("res://demo/moving_duel.tscn").instantiate()
	root.add_child(_duel)


func _physics_process(_delta: float) -> bool:
	_frames += 1
	_step_frames += 1
	if _frames == 1:
		_you = _duel.get("_fighters")[0]
		_you.controller.punch_started.connect(func(_move, _hand, _combo_index): _report.styles.append(_you.style))
	match _step:
		0:  # the autopilot plays a second, then W is held
			if _frames == 120:
				_report.driver_before = _you.driver
				_mark.distance = _you.distance()
				_next(KEY_W, true)
		1:  # walk in until the opponent is within the straight's reach, then punch
			if _you.distance() < 0.8 or _step_frames > 240:
				_report.closed_m = _mark.distance - _you.distance()
				_report.driver_after = _you.driver
				_key(KEY_W, false)
				_tap(KEY_SPACE)
				_report.punches.append(_you.controller.is_punching())
				_next(KEY_2, false)
		2:  # the hook, circling to the right (D) while it punches
			if _step_frames == 1:
				_tap(KEY_2)
				_key(KEY_D, true)
				_mark.angle = _bearing()
			elif _step_frames == 60:
				_tap(KEY_SPACE)
				_report.punches.append(_you.controller.is_punching())
			elif _step_frames == 150:
				_key(KEY_D, false)
				_report.circled_rad = angle_difference(_mark.angle, _bearing())
				var to_opponent: Vector3 = _you.opponent.mover.global_position - _you.mover.global_position
				_report.facing_error_rad = absf(angle_difference(_you.mover.rotation.y, atan2(to_opponent.x, to_opponent.z)))
				_mark.distance = _you.distance()
				_next(KEY_S, true)
		3:  # back off
			if _step_frames == 60:
				_key(KEY_S, false)
				_report.backed_m = _you.distance() - _mark.distance
				_report.hits = _you.hits
				print("MOVING_DUEL_KEYS ", JSON.stringify(_report))
				quit(0)
	return false


## Where you stand, seen from the opponent (radians of yaw): circling changes it.
func _bearing() -> float:
	var from_opponent: Vector3 = _you.mover.global_position - _you.opponent.mover.global_position
	return atan2(from_opponent.x, from_opponent.z)


func _next(key: Key, press: bool) -> void:
	_step += 1
	_step_frames = 0
	if press:
		_key(key, true)


func _key(key: Key, pressed: bool) -> void:
	var event := InputEventKey.new()
	event.physical_keycode = key
	event.keycode = key
	event.pressed = pressed
	Input.parse_input_event(event)
	Input.flush_buffered_events()


func _tap(key: Key) -> void:
	_key(key, true)
	_key(key, false)
