"""What a punch did, read from its per-frame features: the right fist's first contact with the bag, peak
speed, time and point of impact. Used by the search and training reports and by `punch replay`."""

from __future__ import annotations

import numpy as np

from punch_trainer.reward.rewards import first_right_contact


def motion_report(dataset: dict[str, np.ndarray]) -> dict[str, float | list[float] | None]:
    """Peak fist speed, time to impact and contact point (relative to the bag's centre) of a trajectory."""
    names = [str(n) for n in dataset["feature_names"]]
    f = dataset["features"]
    col = names.index
    velocity = f[:, col("fist_r_vel_x"):col("fist_r_vel_z") + 1]
    speed = np.linalg.norm(velocity, axis=1)
    hit, first = first_right_contact(f, names)
    hz = float(dataset["physics_hz"])
    report: dict[str, float | list[float] | None] = {
        "peak_fist_speed_mps": float(speed.max()),
        "peak_fist_speed_time_s": float((speed.argmax() + 1) / hz),
        "closest_fist_bag_distance_m": float(f[:, col("fist_r_bag_distance")].min()),
        "impact_time_s": None, "impact_speed_mps": None, "contact_point_from_bag_centre_m": None,
    }
    if hit:
        frame = int(first)
        fist = f[frame, col("fist_r_pos_x"):col("fist_r_pos_z") + 1]
        bag = f[frame, col("bag_pos_x"):col("bag_pos_z") + 1]
        report.update(impact_time_s=(frame + 1) / hz, impact_speed_mps=float(speed[max(frame - 1, 0)]),
                      contact_point_from_bag_centre_m=[round(float(v), 4) for v in fist - bag])
    return report


