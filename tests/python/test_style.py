"""The motion style (punch_trainer.reward.style): what it costs, how it discounts a reward, its names."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from punch_trainer.reward.style import (
    STYLES,
    Style,
    StyleError,
    load_style_file,
    reach_share,
    running_peak_frame,
    style_from_label,
    style_label,
    style_named,
)
from punch_trainer.scene import SCENE_ARM_LENGTHS_M, SCENE_BAG_RADIUS_M

FRAMES = 50
NAMES = [f"{stem}_{axis}" for stem in ("fist_l_pos", "fist_l_vel", "fist_r_vel", "fist_r_pos", "fist_r_impulse",
                                        "character_impulse", "bag_pos", "root_vel", "root_spin")
         for axis in "xyz"] + ["angle_waist_flexion"]
"""every feature the style reads"""


def features(**columns: np.ndarray) -> dict[str, np.ndarray]:
    """Per-frame features of one punch: every feature the style reads, 0 unless given."""
    values = {name: np.zeros(FRAMES) for name in NAMES}
    values.update(columns)
    return values


def frames_of(values: dict[str, np.ndarray]):  # noqa: ANN201 - a FramesLike
    return values.__getitem__


def test_a_punch_within_the_free_ranges_costs_nothing_and_keeps_its_reward() -> None:
    style = Style("boxing")
    calm = features(fist_l_pos_x=np.linspace(0, 0.07, FRAMES), fist_r_vel_z=np.full(FRAMES, 8.0),
                    angle_waist_flexion=np.full(FRAMES, np.radians(10.0)))
    assert np.all(style.cost(frames_of(calm)) == 0.0)
    reward = {"forward": np.linspace(-1.0, 1.0, FRAMES)}
    styled = style.apply(reward, frames_of(calm))
    np.testing.assert_allclose(styled["forward"], reward["forward"], atol=1e-12)


def test_each_excess_costs_and_the_discount_grows_with_the_cost_so_far() -> None:
    style = Style("boxing")
    for column, value in (("fist_l_pos_y", 0.3), ("fist_l_vel_x", 5.0), ("fist_r_vel_z", 12.0),
                          ("angle_waist_flexion", np.radians(30.0))):
        flailing = features(**{column: np.where(np.arange(FRAMES) >= 10, value, 0.0)})
        cost = style.cost(frames_of(flailing))
        assert np.all(cost[:10] == 0.0) and np.all(cost[10:] > 0.0), column
        styled = style.apply({"forward": np.ones(FRAMES), "back": -np.ones(FRAMES)}, frames_of(flailing))
        np.testing.assert_allclose(styled["forward"][:10], 1.0, atol=1e-12)  # nothing to discount yet
        so_far = np.cumsum(styled["forward"])
        assert np.all(np.diff(so_far[10:]) < 1.0), column  # each frame earns less than the reward alone
        assert np.all(so_far > -1e-9), column  # a hit still does no worse than standing still
        every_cost = np.cumsum(cost)  # each frame's earnings x exp(-cost up to it - the share of the cost after it)
        expected = np.exp(-every_cost - style.later_cost_share * (every_cost[-1] - every_cost)).sum()
        np.testing.assert_allclose(so_far[-1], expected, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(styled["back"], -np.ones(FRAMES))  # losses are not discounted


def test_a_body_carried_by_its_game_is_not_charged_for_its_walk_or_its_turn() -> None:
    """Fist speeds are measured on the body: walking at 2 m/s and turning at 3 rad/s carry the guard hand at
    over 2 m/s in the world, and cost nothing; the same speed of the hand alone costs."""
    style = Style("boxing")
    walk, spin = np.full(FRAMES, 2.0), np.full(FRAMES, 3.0)
    guard = {"fist_l_pos_x": np.full(FRAMES, 0.18), "fist_l_pos_z": np.full(FRAMES, 0.3)}
    # The guard hand's world velocity: the walk plus (0, 3, 0) x (0.18, 0, 0.3) = (0.9, 0, -0.54).
    carried = features(**guard, root_vel_z=walk, root_spin_y=spin, fist_l_vel_x=np.full(FRAMES, 0.9),
                       fist_l_vel_z=np.full(FRAMES, 2.0 - 0.54), fist_r_vel_z=walk)
    assert np.all(style.cost(frames_of(carried)) == 0.0)
    flailing = features(**guard, fist_l_vel_x=np.full(FRAMES, 0.9), fist_l_vel_z=np.full(FRAMES, 2.0))
    assert np.all(style.cost(frames_of(flailing)) > 0.0)


def test_drawing_the_fist_back_before_it_lands_costs_and_its_rebound_after_does_not() -> None:
    style = Style("boxing")
    ahead = {"bag_pos_z": np.full(FRAMES, 0.7), "fist_r_pos_z": np.full(FRAMES, 0.2)}  # the bag straight ahead
    wind_up = features(**ahead, fist_r_vel_z=np.where(np.arange(FRAMES) < 10, -3.0, 0.0))
    assert np.all(style.cost(frames_of(wind_up))[:10] > 0.0) and np.all(style.cost(frames_of(wind_up))[10:] == 0.0)
    straight_in = features(**ahead, fist_r_vel_z=np.full(FRAMES, 3.0))
    assert np.all(style.cost(frames_of(straight_in)) == 0.0)
    landed = np.where(np.arange(FRAMES) == 20, 1.0, 0.0)
    rebound = features(**ahead, fist_r_impulse_z=landed, fist_r_vel_z=np.where(np.arange(FRAMES) > 20, -3.0, 0.0))
    assert np.all(style.cost(frames_of(rebound)) == 0.0)


def test_the_chain_style_charges_a_joint_that_leads_the_one_before_it_and_boxing_does_not() -> None:
    """`boxing_chain`: waist rotation, then shoulder, then elbow (each relative to a captured peak) costs nothing;
    the elbow snapping straight before the waist and shoulder turn costs, until the fist lands."""
    ramp = lambda start: np.clip((np.arange(FRAMES) - start) / 5.0, 0.0, 1.0)  # noqa: E731
    speeds = {"speed_waist_rotation": 3.0 * ramp(0), "speed_shoulder_r_flexion": 10.0 * ramp(2),
              "speed_shoulder_r_rotation": np.zeros(FRAMES), "speed_shoulder_r_abduction": np.zeros(FRAMES),
              "speed_elbow_r_extension": 18.0 * ramp(4)}
    chain = Style("chain", chain_cost=4.0)
    assert chain is not None and chain.chain_cost > 0
    assert np.all(chain.cost(frames_of(features(**speeds))) == 0.0)
    elbow_first = {**speeds, "speed_elbow_r_extension": 18.0 * ramp(-5)}
    cost = chain.cost(frames_of(features(**elbow_first)))
    assert cost[0] > 0.0 and cost[FRAMES - 1] == 0.0  # once the shoulder has caught up, nothing
    landed = features(**elbow_first, fist_r_impulse_z=np.ones(FRAMES))
    assert np.all(chain.cost(frames_of(landed)) == 0.0)
    assert np.all(Style("boxing").cost(frames_of(features(**elbow_first))) == 0.0)


def peaking_at(waist: int, shoulder: int, elbow: int, contact: int) -> dict[str, np.ndarray]:
    """A punch whose waist rotation, shoulder and elbow speeds peak at the given frames, touching the bag from
    `contact` on (its impulse), whose fist earns 1 a frame until then."""
    frame = np.arange(FRAMES)
    bump = lambda peak: np.exp(-0.5 * (frame - peak) ** 2)  # noqa: E731
    return features(speed_waist_rotation=-3.0 * bump(waist), speed_shoulder_r_flexion=10.0 * bump(shoulder),
                    speed_shoulder_r_rotation=np.zeros(FRAMES), speed_shoulder_r_abduction=np.zeros(FRAMES),
                    speed_elbow_r_extension=18.0 * bump(elbow), fist_r_impulse_z=np.where(frame >= contact, 1.0, 0.0))


def test_the_order_charges_a_punch_by_the_frames_its_peaks_break_the_order_at_contact() -> None:
    """A punch's order charges add up to the frames by which the peaks until the first contact break the
    proximal-to-distal order (docs/naturalness.md); a tie is in order; a joint still speeding up at contact peaks
    there (what comes after does not count); nothing is charged after contact; a punch that never touches is
    charged its peaks over the whole episode."""
    order = Style("order", order_cost_per_frame=0.3)
    for peaks, frames_out in (((2, 2, 5), 0), ((6, 2, 3), 4), ((3, 5, 4), 1), ((3, 4, 20), 0), ((20, 2, 3), 6)):
        punch = frames_of(peaking_at(*peaks, contact=8))
        charge = order.whole_punch_cost(punch)
        np.testing.assert_allclose(charge.sum(), 0.3 * frames_out, err_msg=str(peaks))
        assert np.all(charge[9:] == 0.0) and np.all(order.cost(punch) == 0.0)
        assert np.all(Style("boxing").whole_punch_cost(punch) == 0.0)
    missed = frames_of(peaking_at(20, 2, 3, contact=FRAMES))
    np.testing.assert_allclose(order.whole_punch_cost(missed).sum(), 0.3 * 18)  # stopping short does not escape it
    ordered = Style("ordered", order_cost_per_frame=1.0, order_margin_frames=1)  # each joint a frame before the next
    assert ordered is not None and ordered.order_margin_frames == 1 and not ordered.order_charged_at_contact
    for peaks, frames_out in (((1, 2, 3), 0), ((2, 2, 5), 1), ((2, 2, 2), 2), ((6, 2, 3), 5)):
        charge = ordered.whole_punch_cost(frames_of(peaking_at(*peaks, contact=8)))
        np.testing.assert_allclose(charge.sum(), ordered.order_cost_per_frame * frames_out, err_msg=str(peaks))
    # The first form charges all on the contact frame, and a miss nothing.
    at_contact = Style("order", order_cost_per_frame=0.3, order_charged_at_contact=True)
    assert at_contact is not None and at_contact.order_charged_at_contact
    charge = at_contact.whole_punch_cost(frames_of(peaking_at(6, 2, 3, contact=8)))
    np.testing.assert_allclose(charge[8], at_contact.order_cost_per_frame * 4)
    assert np.all(np.delete(charge, 8) == 0.0) and np.all(at_contact.whole_punch_cost(missed) == 0.0)


def test_the_order_charge_is_nothing_exactly_when_the_naturalness_report_counts_the_punch_in_order() -> None:
    """The charge trained with and the order measured (report/naturalness.py) read the same speeds to the same
    contact, so a policy cannot be trained to one order and measured by another."""
    from punch_trainer.report.naturalness import in_proximal_to_distal_order
    from punch_trainer.reward.style import chain_speeds

    order = Style("order", order_cost_per_frame=1.0)
    rng = np.random.default_rng(5)
    for _ in range(200):
        contact = int(rng.integers(3, FRAMES))
        punch = peaking_at(*rng.integers(0, 12, 3), contact=contact)
        for name in ("speed_waist_rotation", "speed_shoulder_r_rotation", "speed_elbow_r_extension"):
            punch[name] = punch[name] + rng.normal(0.0, 2.0, FRAMES)
        waist, shoulder, elbow = (speed[:contact + 1] for speed in chain_speeds(frames_of(punch)))
        charged = order.whole_punch_cost(frames_of(punch)).sum() > 0
        assert charged != in_proximal_to_distal_order(waist, shoulder, elbow)


def test_the_running_peak_frame_is_the_first_frame_of_the_largest_value_so_far() -> None:
    values = np.array([[0.0, 1.0, 1.0, 3.0, 2.0, 3.0, 5.0, -1.0]])
    np.testing.assert_array_equal(running_peak_frame(values), [[0, 1, 1, 3, 3, 3, 6, 6]])


def test_the_order_charge_takes_what_the_punch_earned_before_it_too() -> None:
    """Unlike the other costs (a tenth of them reaches back), the order's charge discounts the whole punch: a punch
    cannot earn before it lands and escape the charge by landing early."""
    order = Style("ordered", order_cost_per_frame=1.0, order_margin_frames=1)
    assert order is not None
    earned = {"forward": np.where(np.arange(FRAMES) < 8, 1.0, 0.0)}
    in_order = order.apply(earned, frames_of(peaking_at(1, 2, 5, contact=8)))["forward"].sum()
    out_of_order = order.apply(earned, frames_of(peaking_at(6, 2, 3, contact=8)))["forward"].sum()
    assert in_order == pytest.approx(8.0)
    assert out_of_order == pytest.approx(8.0 * np.exp(-5 * order.order_cost_per_frame))


def test_a_punch_that_has_not_touched_the_bag_by_the_deadline_is_charged_each_frame_until_it_does() -> None:
    """`boxing_ordered_reach`: a reward that pays near the bag without a touch cannot keep the order by stopping
    short; the charge runs from the deadline to the first contact and takes the whole punch's earnings."""
    reach = recipe_style("boxing_ordered_reach")
    assert reach is not None and reach.miss_after_frames > 0
    deadline, cost = reach.miss_after_frames, reach.miss_cost_per_frame
    ordered = Style("ordered", order_cost_per_frame=1.0, order_margin_frames=1)  # the same charge for the order, nothing for a late touch
    assert ordered is not None

    def late_charge(contact: int) -> np.ndarray:
        punch = frames_of(peaking_at(1, 2, 5, contact=contact))
        return reach.whole_punch_cost(punch) - ordered.whole_punch_cost(punch)

    assert np.all(late_charge(deadline) == 0.0)
    frame = np.arange(FRAMES)
    np.testing.assert_allclose(late_charge(deadline + 4), np.where((frame >= deadline) & (frame < deadline + 4), cost, 0.0))
    np.testing.assert_allclose(late_charge(FRAMES).sum(), cost * (FRAMES - deadline))
    earned = {"forward": np.ones(FRAMES)}
    stopped_short = reach.apply(earned, frames_of(peaking_at(1, 2, 5, contact=FRAMES)))["forward"].sum()
    assert stopped_short < 0.1 * reach.apply(earned, frames_of(peaking_at(1, 2, 5, contact=10)))["forward"].sum()


def test_a_capped_order_charge_leaves_a_punch_out_of_order_more_than_a_miss() -> None:
    """`boxing_ordered_capped`: the order's charge stops at its cap, so a short arm that reaches the bag only out of
    order still earns more by landing than by stopping short, and a punch in order earns the most."""
    capped = Style("ordered_capped", order_cost_per_frame=1.0, order_margin_frames=1, order_cost_cap=1.0, miss_after_frames=24, miss_cost_per_frame=0.5)
    assert capped is not None and np.isfinite(capped.order_cost_cap)
    far_out = frames_of(peaking_at(6, 2, 3, contact=8))
    np.testing.assert_allclose(capped.whole_punch_cost(far_out).sum(), capped.order_cost_cap)
    earned = {"forward": np.ones(FRAMES)}
    landed_in_order = capped.apply(earned, frames_of(peaking_at(1, 2, 5, contact=8)))["forward"].sum()
    landed_out_of_order = capped.apply(earned, far_out)["forward"].sum()
    missed = capped.apply(earned, frames_of(peaking_at(6, 2, 3, contact=FRAMES)))["forward"].sum()
    assert landed_in_order > landed_out_of_order > 5 * missed


def test_the_near_order_charge_leaves_a_target_beyond_the_arms_stretch_to_land_out_of_order() -> None:
    """`boxing_ordered_capped2_near`: a punch out of order is charged where the bag starts within 1.25 arm's lengths
    of the shoulder and not beyond, where only a short arm's full stretch with the trunk's lean reaches it."""
    near = recipe_style("boxing_ordered_capped2_near")
    assert near is not None and near.order_reach_share == 1.25
    for distance_m, charged in ((0.6, near.order_cost_cap), (1.0, 0.0)):  # 0.73 and 1.36 arm's lengths
        out_of_order = frames_of({**peaking_at(6, 2, 3, contact=8), **WITHIN_REACH, "bag_pos_z": np.full(FRAMES, distance_m)})
        assert (reach_share(out_of_order)[0] <= near.order_reach_share) == (charged > 0.0)
        np.testing.assert_allclose(near.whole_punch_cost(out_of_order).sum(), charged)


def test_the_clean_straight_charges_a_bag_touched_elsewhere_before_the_fist_once_and_nothing_else() -> None:
    """`boxing_straight_ordered_clean`: the forearm (the whole character's impulse, less the punching fist's)
    touching the bag before the fist is charged once, on its first frame; touching with the fist first, or with
    the forearm beside the fist from then on, is not; the order's charge is the floor style's."""
    clean, floor = recipe_style("boxing_straight_ordered_clean"), recipe_style("boxing_straight_ordered_floor")
    assert clean is not None and floor is not None and clean.arm_first_cost > 0.0
    fist_at_20 = {**peaking_at(6, 2, 10, contact=20), "fist_r_bag_distance": np.full(FRAMES, 1.0)}
    forearm_at_14 = {"character_impulse_z": np.where(np.arange(FRAMES) >= 14, 1.0, 0.0) + fist_at_20["fist_r_impulse_z"]}

    def arm_first_charge(contacts: dict[str, np.ndarray]) -> np.ndarray:
        punch = frames_of({**fist_at_20, **contacts})
        return np.asarray(clean.whole_punch_cost(punch) - floor.whole_punch_cost(punch))

    charge = arm_first_charge(forearm_at_14)
    np.testing.assert_allclose(charge[14], clean.arm_first_cost)
    assert np.all(np.delete(charge, 14) == 0.0)
    fist_only = {"character_impulse_z": fist_at_20["fist_r_impulse_z"]}
    beside = {"character_impulse_z": 2.0 * fist_at_20["fist_r_impulse_z"]}  # fist and forearm from the same frame
    assert np.all(arm_first_charge(fist_only) == 0.0) and np.all(arm_first_charge(beside) == 0.0)
    earned = {"forward": np.ones(FRAMES)}
    kept = [clean.apply(earned, frames_of({**fist_at_20, **contacts}))["forward"].sum() for contacts in (fist_only, forearm_at_14)]
    assert kept[1] < 0.2 * kept[0]  # the forearm's push keeps little of what the punch earned


def test_the_capped_straight_keeps_part_of_what_a_landing_out_of_order_earned() -> None:
    """`boxing_straight_ordered_capped`: `_clean` with the order's charge stopping at its cap, so a punch thrown out
    of order (by a designer's noise) keeps exp(-cap) of what it earned, where `_clean` keeps next to nothing; in
    order it costs what `_clean` does."""
    capped, clean = Style("straight_ordered_capped", fist_free_mps=6.3, fist_cost_per_mps2=0.5, landing_free_mps=6.2, landing_cost_per_mps2=1.0, order_cost_per_frame=1.0, order_margin_frames=1, order_cost_cap=1.0, arm_first_cost=3.0), recipe_style("boxing_straight_ordered_clean")
    assert capped is not None and clean is not None and capped.order_cost_cap == 1.0
    assert capped.arm_first_cost == clean.arm_first_cost
    far_out = frames_of({**peaking_at(9, 2, 1, contact=12), "fist_r_bag_distance": np.full(FRAMES, 1.0)})
    np.testing.assert_allclose(capped.whole_punch_cost(far_out).sum(), capped.order_cost_cap)
    assert clean.whole_punch_cost(far_out).sum() > capped.order_cost_cap
    in_order = frames_of(peaking_at(1, 2, 5, contact=8))
    np.testing.assert_allclose([capped.whole_punch_cost(in_order).sum(), clean.whole_punch_cost(in_order).sum()], 0.0, atol=1e-12)
    earned = {"forward": np.ones(FRAMES)}
    assert capped.apply(earned, far_out)["forward"].sum() > 5 * clean.apply(earned, far_out)["forward"].sum()


def test_the_near_clean_straight_leaves_a_bag_beyond_the_arms_length_to_whatever_touches_it_first() -> None:
    """`boxing_straight_ordered_clean_near`: the forearm first is charged where the bag starts within the arm's
    length of the shoulder, and not beyond, where a short arm leans in and its trunk may meet the bag first."""
    near = Style("straight_ordered_clean_near", fist_free_mps=6.3, fist_cost_per_mps2=0.5, landing_free_mps=6.2, landing_cost_per_mps2=1.0, order_cost_per_frame=1.0, order_margin_frames=1, arm_first_cost=3.0, arm_first_reach_share=1.0)
    assert near is not None and near.arm_first_reach_share == 1.0
    frame = np.arange(FRAMES)
    fist_at_20 = {**peaking_at(6, 2, 10, contact=20), **WITHIN_REACH, "fist_r_bag_distance": np.full(FRAMES, 1.0)}
    trunk_at_14 = {"character_impulse_z": np.where(frame >= 14, 1.0, 0.0) + fist_at_20["fist_r_impulse_z"]}
    for distance_m, charged in ((0.6, near.arm_first_cost), (1.0, 0.0)):  # 0.69 and 1.33 arm's lengths
        punch = frames_of({**fist_at_20, **trunk_at_14, "bag_pos_z": np.full(FRAMES, distance_m)})
        without = frames_of({**fist_at_20, "character_impulse_z": fist_at_20["fist_r_impulse_z"], "bag_pos_z": np.full(FRAMES, distance_m)})
        np.testing.assert_allclose((near.whole_punch_cost(punch) - near.whole_punch_cost(without)).sum(), charged)


def landing(**columns: np.ndarray) -> dict[str, np.ndarray]:
    """A punch whose fist closes on the bag's centre from 0.6 to 0.2 m, within 0.3 m (landing) from frame 38."""
    return features(**{"fist_r_bag_distance": np.linspace(0.6, 0.2, FRAMES), "speed_waist_rotation": np.zeros(FRAMES),
                       **columns})


WITHIN_REACH = {"body_upper_arm_m": np.full(FRAMES, SCENE_ARM_LENGTHS_M[0]), "body_forearm_m": np.full(FRAMES, SCENE_ARM_LENGTHS_M[1]),
                "body_shoulder_width_m": np.full(FRAMES, SCENE_ARM_LENGTHS_M[2]), "bag_pos_z": np.full(FRAMES, 0.6)}
"""the scene's arms and a bag 0.6 m ahead: well within the arm's reach (0.69 of it)"""


def test_the_fast_style_charges_a_slow_landing_and_nothing_else() -> None:
    """`boxing_fast`: the fist landing slower than a boxer's 8.5 m/s costs, only inside the landing zone and
    before contact; a fast landing, or a slow fist far from the bag, costs nothing, and `boxing` never charges it."""
    fast = Style("fast", landing_free_mps=8.5, landing_cost_per_mps2=0.2)
    assert fast is not None and fast.landing_cost_per_mps2 > 0
    zone = np.linspace(0.6, 0.2, FRAMES) < fast.landing_zone_m
    slow = fast.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 6.0))))
    assert np.all(slow[zone] > 0.0) and np.all(slow[~zone] == 0.0)
    np.testing.assert_allclose(slow[zone], fast.landing_cost_per_mps2 * (fast.landing_free_mps - 6.0) ** 2)
    assert np.all(fast.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 8.8)))) == 0.0)
    touched = np.where(np.arange(FRAMES) >= 40, 1.0, 0.0)
    landed = fast.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 6.0), fist_r_impulse_z=touched)))
    assert np.all(landed[40:] == 0.0) and np.all(landed[zone & (np.arange(FRAMES) < 40)] > 0.0)
    assert np.all(Style("boxing").cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 6.0)))) == 0.0)


def test_the_straight_style_charges_a_fist_faster_than_a_boxers_straight_where_boxing_does_not() -> None:
    """`boxing_straight`: the punching fist beyond 6.5 m/s costs with the square of the excess, as `boxing`'s beyond
    9 m/s; a fist at 8 m/s is free with `boxing` and charged with it."""
    straight = recipe_style("boxing_straight")
    assert straight is not None and straight.fist_free_mps < Style("boxing").fist_free_mps
    at_8_mps = frames_of(features(fist_r_vel_z=np.full(FRAMES, 8.0)))
    np.testing.assert_allclose(straight.cost(at_8_mps), straight.fist_cost_per_mps2 * (8.0 - straight.fist_free_mps) ** 2)
    assert np.all(Style("boxing").cost(at_8_mps) == 0.0)
    assert np.all(straight.cost(frames_of(features(fist_r_vel_z=np.full(FRAMES, 6.4)))) == 0.0)


def test_the_late_style_charges_a_first_contact_before_its_frame_once_and_a_later_one_nothing() -> None:
    """`boxing_late`: the first contact frame, if it comes before `contact_not_before_frames`, costs per frame early,
    on that frame only; a later first contact, and any contact with `boxing`, costs nothing."""
    late = Style("late", contact_not_before_frames=16, early_contact_cost_per_frame=0.2)
    assert late is not None and late.early_contact_cost_per_frame > 0 and late.contact_not_before_frames == 16
    for first, expected in ((10, late.early_contact_cost_per_frame * 6), (20, 0.0)):
        touched = frames_of(features(fist_r_impulse_z=np.where(np.arange(FRAMES) >= first, 1.0, 0.0)))
        cost = late.cost(touched)
        np.testing.assert_allclose(cost[first], expected)
        assert np.all(np.delete(cost, first) == 0.0)
        assert np.all(Style("boxing").cost(touched) == 0.0)


def test_the_arm_style_asks_a_shorter_arm_for_a_slower_landing() -> None:
    """`boxing_fast_arm`: the floor is 8.5 m/s with the scene's arms and scales with the arm's length, so 7 m/s
    lands free with arms 0.75 times as long (floor 6.4 m/s) and costs with the scene's."""
    arm = Style("fast_arm", landing_free_mps=8.5, landing_cost_per_mps2=0.2, landing_floor_with_arm=True)
    assert arm is not None and arm.landing_floor_with_arm
    upper_m, forearm_m, _ = SCENE_ARM_LENGTHS_M

    def cost(scale: float) -> np.ndarray:
        return arm.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 7.0), body_upper_arm_m=np.full(FRAMES, scale * upper_m),
                                          body_forearm_m=np.full(FRAMES, scale * forearm_m))))

    zone = np.linspace(0.6, 0.2, FRAMES) < arm.landing_zone_m
    np.testing.assert_allclose(cost(1.0)[zone], arm.landing_cost_per_mps2 * 1.5 ** 2)
    assert np.all(cost(0.75) == 0.0)


def test_the_near_style_leaves_a_target_beyond_the_arm_to_a_slower_punch() -> None:
    """`boxing_fast_near`: the floor counts only where the bag's near side starts within 1.1 arm lengths of the
    shoulder (across the ground): a target 0.75 m ahead is near for the scene's arm (0.96 of it) and far for an
    arm 0.75 times as long (1.28), and the same slow landing costs only the first."""
    near = Style("fast_near", landing_free_mps=8.5, landing_cost_per_mps2=0.2, landing_reach_share=1.1)
    assert near is not None and near.landing_reach_share == 1.1
    upper_m, forearm_m, width_m = SCENE_ARM_LENGTHS_M

    def cost(scale: float, ahead_m: float, side_m: float = 0.0, shoulder_shift_m: float = 0.0) -> np.ndarray:
        full = np.full(FRAMES, 1.0)
        return near.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, 6.0), body_upper_arm_m=scale * upper_m * full,
                                           body_forearm_m=scale * forearm_m * full,
                                           body_shoulder_width_m=(width_m + 2 * shoulder_shift_m) * full,
                                           bag_pos_z=ahead_m * full, bag_pos_x=side_m * full)))

    zone = np.linspace(0.6, 0.2, FRAMES) < near.landing_zone_m
    np.testing.assert_allclose(cost(1.0, 0.75)[zone], near.landing_cost_per_mps2 * 2.5 ** 2)
    assert np.all(cost(0.75, 0.75) == 0.0)
    assert np.all(cost(0.75, 0.6, -0.18)[zone] > 0.0)  # straight out from the shoulder: near for the short arm too
    assert np.all(cost(1.0, 0.85, 0.25) == 0.0)  # across the body at the volume's far corner: beyond every arm
    # Across the body, 0.75 m ahead and 0.22 m left: near for the scene's shoulders (1.09), far once they sit 4 cm
    # wider each (1.12), as a rig's may (the right shoulder further from a bag on the left).
    assert np.all(cost(1.0, 0.75, 0.22)[zone] > 0.0) and np.all(cost(1.0, 0.75, 0.22, shoulder_shift_m=0.04) == 0.0)
    sandbag = (Path(__file__).parents[2] / "addons/punch_controller/scenes/punch_sandbag.tscn").read_text()
    assert f"radius = {SCENE_BAG_RADIUS_M}" in sandbag, "the style's bag radius is the sandbag scene's"


def test_the_entry_style_charges_a_slow_landing_once_and_at_most_its_cap() -> None:
    """`boxing_fast_entry`: the shortfall is charged on the first landing frame only, and at most 1.5 m/s of it, so a
    punch landing at 2 m/s (one recovering from a knock) keeps part of what it earns; one at 8 m/s pays a little."""
    entry = Style("fast_entry", landing_free_mps=8.5, landing_cost_per_mps2=0.4, landing_reach_share=1.1, landing_at_entry=True, landing_shortfall_cap_mps=1.5)
    assert entry is not None and entry.landing_at_entry
    first = int(np.argmax(np.linspace(0.6, 0.2, FRAMES) < entry.landing_zone_m))
    for speed_mps, shortfall_mps in ((2.0, 1.5), (8.0, 0.5), (9.0, 0.0)):
        cost = entry.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, speed_mps), **WITHIN_REACH)))
        np.testing.assert_allclose(cost[first], entry.landing_cost_per_mps2 * shortfall_mps ** 2)
        assert np.all(np.delete(cost, first) == 0.0)


def test_the_capped_style_charges_every_landing_frame_at_most_its_cap() -> None:
    """`boxing_fast_capped`: `boxing_fast_near`'s charge on every landing frame, of at most 1.5 m/s of shortfall."""
    capped = Style("fast_capped", landing_free_mps=8.5, landing_cost_per_mps2=0.2, landing_reach_share=1.1, landing_shortfall_cap_mps=1.5)
    assert capped is not None and not capped.landing_at_entry
    zone = np.linspace(0.6, 0.2, FRAMES) < capped.landing_zone_m
    for speed_mps, shortfall_mps in ((2.0, 1.5), (8.0, 0.5)):
        cost = capped.cost(frames_of(landing(fist_r_vel_z=np.full(FRAMES, speed_mps), **WITHIN_REACH)))
        np.testing.assert_allclose(cost[zone], capped.landing_cost_per_mps2 * shortfall_mps ** 2)
        assert np.all(cost[~zone] == 0.0)


def test_the_lead_style_charges_a_waist_still_speeding_up_as_the_punch_lands() -> None:
    """`boxing_lead`: the waist's turn peaking before the fist is landing costs nothing; still speeding up
    inside the landing zone (the break in the shipped punches' proximal-to-distal order) costs."""
    lead = Style("lead", waist_lead_cost=0.5)
    assert lead is not None and lead.waist_lead_cost > 0
    frame = np.arange(FRAMES)
    peaked_before = lead.cost(frames_of(landing(speed_waist_rotation=np.minimum(frame, 60 - frame) / 5.0)))
    assert np.all(peaked_before == 0.0)  # speeds up to frame 30, slows down from there
    still_speeding = lead.cost(frames_of(landing(speed_waist_rotation=-frame / 5.0)))  # either way round
    zone = np.linspace(0.6, 0.2, FRAMES) < lead.landing_zone_m
    assert np.all(still_speeding[zone] > 0.0) and np.all(still_speeding[~zone] == 0.0)
    assert np.all(Style("boxing").cost(frames_of(landing(speed_waist_rotation=frame / 5.0))) == 0.0)


def test_flailing_after_the_punch_has_landed_costs_what_it_earned() -> None:
    """Earnings stay partly at risk until the punch ends: a guard hand that flies off after the fist lands
    discounts what the fist earned, where a discount of later frames only would let it go free."""
    style = Style("boxing")
    landed = np.where(np.arange(FRAMES) < 20, 1.0, 0.0)  # earned in the first 20 frames, nothing after
    calm = features()
    after = features(fist_l_pos_y=np.where(np.arange(FRAMES) >= 30, 0.12, 0.0))
    calm_return = style.apply({"forward": landed}, frames_of(calm))["forward"].sum()
    after_return = style.apply({"forward": landed}, frames_of(after))["forward"].sum()
    assert calm_return == pytest.approx(20.0)
    assert 0.0 < after_return < 0.9 * calm_return
    assert Style("boxing", later_cost_share=0.0).apply({"forward": landed}, frames_of(after))["forward"].sum() == pytest.approx(20.0)


ROOT = Path(__file__).resolve().parents[2]
RECIPE_STYLES = ROOT / "recipes" / "styles.toml"


def recipe_style(name: str) -> Style:
    """A style of the shipped policies' recipes (recipes/styles.toml)."""
    style = style_named(f"{RECIPE_STYLES}:{name}")
    assert style is not None
    return style


def test_the_weight_scales_the_cost() -> None:
    flailing = frames_of(features(fist_l_pos_y=np.full(FRAMES, 0.3)))
    once, twice = style_named("boxing", 1.0), style_named("boxing", 2.0)
    assert once is not None and twice is not None
    np.testing.assert_allclose(twice.cost(flailing), 2.0 * once.cost(flailing))


def test_none_and_a_zero_weight_are_no_style_and_labels_round_trip() -> None:
    assert style_named("none") is None and style_named("boxing", 0.0) is None
    assert style_label(None) == "none" and style_from_label("none") is None
    style = style_named("boxing", 0.5)
    assert style_label(style) == "boxing@0.5" and style_from_label("boxing@0.5") == style


@pytest.mark.parametrize("name, weight", [("gangnam", 1.0), ("boxing", -1.0), ("boxing", float("nan")),
                                          ("boxing", float("inf")), ("boxing", 1e9)])
def test_unknown_styles_and_senseless_weights_are_refused(name: str, weight: float) -> None:
    with pytest.raises(StyleError):
        style_named(name, weight)
    with pytest.raises(StyleError):
        style_from_label("boxing@heavy")


def test_the_search_sigma_cap_has_one_value_per_degree_of_freedom() -> None:
    style = Style("boxing")
    assert style.search_sigma_cap(10).shape == (10,)
    with pytest.raises(StyleError):
        style.search_sigma_cap(12)


def test_a_reward_with_a_style_is_scored_with_it() -> None:
    from dataclasses import replace

    from punch_trainer.reward.rewards import load_reward, score_terms

    names = [*NAMES, "fist_r_bag_distance", "exploit_flags"]
    values = np.zeros((2, FRAMES, len(names)))
    values[..., names.index("fist_r_vel_z")] = 5.0  # toward the bag, close to it: the straight earns every frame
    values[1, 10:, names.index("fist_l_pos_y")] = 0.4  # the second punch's guard hand flies off
    plain = load_reward("straight")
    styled = replace(plain, style=style_named("boxing"))
    plain_returns, _ = score_terms(plain, values, names)
    styled_returns, terms = score_terms(styled, values, names)
    assert plain_returns[0] == plain_returns[1] and styled_returns[0] == pytest.approx(plain_returns[0])
    assert styled_returns[1] < 0.5 * plain_returns[1] and set(terms) == {"forward"}


def test_an_episode_scored_decision_by_decision_adds_up_to_its_return_with_and_without_a_style() -> None:
    """A2C, validation and the env score decision by decision; the style's discount depends on the episode so
    far, so the decisions' rewards must add up to the return the search gives the whole episode."""
    from dataclasses import replace

    from punch_trainer.reward.rewards import (
        EpisodeScorer,
        decision_rewards,
        load_reward,
        score,
    )

    names = [*NAMES, "fist_r_bag_distance", "exploit_flags", "speed_waist_rotation", "body_upper_arm_m", "body_forearm_m",
             "body_shoulder_width_m", "speed_shoulder_r_flexion", "speed_shoulder_r_rotation", "speed_shoulder_r_abduction",
             "speed_elbow_r_extension"]
    rng = np.random.default_rng(3)
    values = np.zeros((3, FRAMES, len(names)))
    values[..., names.index("fist_r_vel_z")] = rng.uniform(0, 12, (3, FRAMES))
    values[..., names.index("fist_l_pos_y")] = np.linspace(0, 0.4, FRAMES)  # the guard hand drifts off
    values[..., names.index("fist_r_bag_distance")] = np.linspace(0.6, 0.2, FRAMES)  # and lands (the landing terms)
    values[..., names.index("speed_waist_rotation")] = rng.uniform(-6, 6, (3, FRAMES))
    for joint in ("shoulder_r_flexion", "shoulder_r_rotation", "shoulder_r_abduction", "elbow_r_extension"):
        values[..., names.index(f"speed_{joint}")] = rng.uniform(-12, 12, (3, FRAMES))
    values[:, 23:, names.index("fist_r_impulse_z")] = 1.0  # touching from a frame inside a decision (the order's charge)
    values[..., names.index("body_upper_arm_m")], values[..., names.index("body_forearm_m")] = 0.25, 0.3
    values[..., names.index("body_shoulder_width_m")], values[..., names.index("bag_pos_z")] = 0.36, 0.6  # within reach
    plain = load_reward("straight")
    tried = [Style("fast", landing_free_mps=8.5, landing_cost_per_mps2=0.2),
             Style("fast_arm", landing_free_mps=8.5, landing_cost_per_mps2=0.2, landing_floor_with_arm=True),
             Style("fast_entry", landing_free_mps=8.5, landing_cost_per_mps2=0.4, landing_reach_share=1.1,
                   landing_at_entry=True, landing_shortfall_cap_mps=1.5),
             Style("lead", waist_lead_cost=0.5), Style("order", order_cost_per_frame=0.3, order_charged_at_contact=True),
             recipe_style("boxing_straight_ordered_floor"), recipe_style("boxing_ordered_capped2_near")]
    for reward in (plain, replace(plain, style=style_named("boxing")), *[replace(plain, style=style) for style in tried]):
        per_decision = decision_rewards(reward, values, names, 5)
        assert per_decision.shape == (3, FRAMES // 5)
        np.testing.assert_allclose(per_decision.sum(axis=-1), score(reward, values, names), rtol=1e-9, atol=1e-9)
        scorer = EpisodeScorer(reward, names)
        for _ in range(2):  # a reset starts the next episode afresh
            scorer.reset()
            steps = [scorer.add(values[:, d * 5:(d + 1) * 5])[0] for d in range(FRAMES // 5)]
            np.testing.assert_array_equal(np.stack(steps, axis=-1), per_decision)
    styled = decision_rewards(replace(plain, style=style_named("boxing")), values, names, 5)
    assert styled[:, -1].sum() < 0.5 * decision_rewards(plain, values, names, 5)[:, -1].sum()  # discounted late

@pytest.mark.godot
@pytest.mark.expensive
def test_a_search_with_the_boxing_style_keeps_the_guard_hand_and_the_trunk_in(tmp_path) -> None:
    """Same seed and budget, at the default placement: the style keeps the guard hand and the trunk within
    what the reward alone lets go, narrows the search there, and still hits (docs/style.md)."""
    from punch_trainer.learn.search import SearchArgs
    from punch_trainer.pipelines.search import run_search
    from punch_trainer.report.naturalness import punch_naturalness
    from punch_trainer.reward.rewards import first_right_contact

    figures, touched = {}, {}
    for style in ("none", "boxing"):
        args = SearchArgs(reward="straight", style=style, iterations=30, rollouts=32, characters_per_process=32,
                          plateau_iterations=0, seed=3, out=tmp_path / style)
        _, result, _ = run_search(args, progress=False)
        figures[style] = punch_naturalness(result.best_features, result.feature_names, 120.0)
        touched[style] = bool(first_right_contact(result.best_features, result.feature_names)[0])
    assert touched["boxing"]
    calm, plain = figures["boxing"], figures["none"]
    assert calm.off_fist_from_guard_m < plain.off_fist_from_guard_m
    assert calm.trunk_flexion_whole_deg < plain.trunk_flexion_whole_deg


def test_the_product_holds_boxing_and_none_and_every_other_style_is_a_file_s() -> None:
    assert set(STYLES) == {"none", "boxing"}
    recipe_styles, tried = load_style_file(RECIPE_STYLES), load_style_file(ROOT / "experiments" / "styles.toml")
    assert not recipe_styles.keys() & tried.keys()
    used = {line.split("=")[1].strip().strip('"') for recipe in (ROOT / "recipes").glob("*.toml")
            for line in recipe.read_text().splitlines() if line.startswith("style =")}
    assert used - {"boxing", "none"} == set(recipe_styles), "recipes/styles.toml holds the styles the recipes use, only those"
    labelled = style_named(f"{RECIPE_STYLES}:boxing_ordered_capped2", 0.5)
    assert labelled is not None and style_label(labelled) == "boxing_ordered_capped2@0.5"


@pytest.mark.parametrize("text, complaint", [
    ("[a]\nchain_cost = 'high'\n", "wrong kind"),
    ("[a]\nfrobnicate = 1.0\n", "sets frobnicate"),
    ("[a]\nname = 'b'\n", "sets name"),
    ("[a]\nbase = 'later'\n[later]\n", "no earlier style"),
    ("[a\n", "not a readable style file"),
])
def test_a_style_file_that_does_not_hold_styles_is_refused(tmp_path: Path, text: str, complaint: str) -> None:
    path = tmp_path / "styles.toml"
    path.write_text(text)
    with pytest.raises(StyleError, match=complaint):
        style_named(f"{path}:a")


def test_a_style_file_s_table_changes_its_base() -> None:
    styles = load_style_file(ROOT / "experiments" / "styles.toml")
    assert styles["boxing_chain"].chain_cost == 4.0 and styles["boxing_chain"].fist_free_mps == Style("boxing").fist_free_mps
    with pytest.raises(StyleError, match="has no style 'gangnam'"):
        style_named(f"{RECIPE_STYLES}:gangnam")
