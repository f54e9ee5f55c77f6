## The demo played as a newcomer plays it: the demo scene with "repeat" off; keys 1-6 (key events, as the OS would
## send them) in the orthodox stance, with the bag nudged to the right (arrow keys) while the cross is picked, then
## the southpaw stance picked in its picker and keys 1-6 again, then "swing (policy)" picked in the move picker. Each
## action waits for its punch to finish (or 30 frames when it should throw none). Prints `DEMO_MOVES <json>`: the
## moves of the controller's moveset, the pickers' items, and per action what was thrown (the signals), with which
## hand, what it hit, the bag's side offset and the demo's "last punch" label; then quits.
extends SceneTree

const MOVES := [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
const WAIT_FOR_NONE_FRAMES := 30
const MAX_FRAMES := 4000

var _demo: Node
var _controller: Node
var _actions: Array[Dictionary] = []
var _current: Dictionary = {}
var _frames := 0
var _waited := 0
var _report := {"moveset": [], "items": [], "stances": [], "throws": []}


func _initialize() -> void:
	_demo = load("res://demo/demo.tscn").instantiate()
	root.add_child(_demo)
	(_demo.get_node("%Repeat") as CheckBox).button_pressed = false
	_controller = _demo.get_node("PunchController")
	_controller.punch_started.connect(func(move, hand, _combo_index):
		_current.started.append([String(move), String(hand)]))
	_controller.hit.connect(func(_impulse, _speed, position, body, _push, hand, _part, _blocked):
		var on_bag: bool = body != null and body == _demo.get("_bag")
		_current.hits.append({"bag": on_bag, "hand": String(hand), "x": _offset(position).x}))
	_controller.punch_finished.connect(func(metrics): _current.finished.append(
		{"move": String(metrics.move), "hand": String(metrics.hand), "ended": metrics.ended, "hits": metrics.hits}))
	var moveset: Resource = _controller.get("moveset")
	if moveset == null:
		moveset = load("res://addons/punch_controller/policies/boxing.tres")
	_report.moveset = Array(moveset.call("moves"))
	_plan()
	_begin(_actions.pop_front(), false)  # the demo's first punch is already asked for


## What the newcomer does, in order: a name for the report, and whether it throws a punch.
func _plan() -> void:
	_add("start", func(): pass)  # the demo's own first punch
	for key in [KEY_2, KEY_RIGHT, KEY_RIGHT, KEY_1, KEY_3, KEY_4, KEY_5, KEY_6]:
		_add_key(key)
	_add("stance southpaw", _pick.bind("%Stance", 1))
	for key in [KEY_1, KEY_2, KEY_3, KEY_4, KEY_5, KEY_6]:
		_add_key(key)
	_add("move swing (policy)", func(): _pick("%Move", _items("%Move").find("swing (policy)")))


## A key: an arrow nudges the bag (and punches again), a digit throws its move when the moveset has a policy for it.
func _add_key(key: Key) -> void:
	var number := key - KEY_1
	var throws: bool = number < 0 or number >= 6 or _report.moveset.has(String(MOVES[number]))
	_add("key %s" % OS.get_keycode_string(key), _tap.bind(key), throws)


func _add(action: String, run: Callable, throws := true) -> void:
	_actions.append({"action": action, "run": run, "throws": throws})


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames > MAX_FRAMES:
		print("DEMO_MOVES ", JSON.stringify(_report))
		quit(1)
		return false
	_waited += 1
	var done: bool = _current.finished.any(func(finished): return finished.ended != "interrupted") \
		if _current.throws else _waited >= WAIT_FOR_NONE_FRAMES
	if not done:
		return false
	_current.stance = _controller.get("stance")
	_current.label = (_demo.get_node("%LastPunch") as Label).text
	_current.bag_x = _demo.call("_bag_offset").x
	_current.erase("run")
	_report.throws.append(_current)
	if _actions.is_empty():
		_report.items = _items("%Move")
		_report.stances = _items("%Stance")
		_report.hit_rate_label = (_demo.get_node("%HitRate") as Label).text
		print("DEMO_MOVES ", JSON.stringify(_report))
		quit(0)
		return false
	_begin(_actions.pop_front(), true)
	return false


func _begin(action: Dictionary, run: bool) -> void:
	_current = action.merged({"started": [], "hits": [], "finished": []})
	_waited = 0
	if run:
		action.run.call()


## A point in the character's frame (+X its left).
func _offset(point: Vector3) -> Vector3:
	return (_demo.get_node("PunchCharacter") as Node3D).global_transform.affine_inverse() * point


func _items(picker_path: String) -> Array[String]:
	var picker: OptionButton = _demo.get_node(picker_path)
	var items: Array[String] = []
	for index in picker.item_count:
		items.append(picker.get_item_text(index))
	return items


## Picks item `index` of an OptionButton as a click does (the selection, then `item_selected`).
func _pick(picker_path: String, index: int) -> void:
	var picker: OptionButton = _demo.get_node(picker_path)
	picker.select(index)
	picker.item_selected.emit(index)


func _tap(key: Key) -> void:
	for pressed in [true, false]:
		var event := InputEventKey.new()
		event.physical_keycode = key
		event.keycode = key
		event.pressed = pressed
		Input.parse_input_event(event)
		Input.flush_buffered_events()
