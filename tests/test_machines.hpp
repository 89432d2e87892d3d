#pragma once
// A machine file the tests share: a three-axis mill with generous travel and the limits of a small machining centre
// (30 m/min, 2.5 m/s^2, 50 m/s^3), for jobs that test what the program and the tools do rather than the drives.

namespace vmsim::test {

inline const char* const kXyzTestMill = R"([machine]
name = "test mill"
kinematics = "xyz"
[[axes]]
name = "X"
type = "linear"
travel_mm = [-100.0, 100.0]
max_velocity_m_per_min = 30.0
max_acceleration_m_per_s2 = 2.5
max_jerk_m_per_s3 = 50.0
[[axes]]
name = "Y"
type = "linear"
travel_mm = [-100.0, 100.0]
max_velocity_m_per_min = 30.0
max_acceleration_m_per_s2 = 2.5
max_jerk_m_per_s3 = 50.0
[[axes]]
name = "Z"
type = "linear"
travel_mm = [-100.0, 100.0]
max_velocity_m_per_min = 30.0
max_acceleration_m_per_s2 = 2.5
max_jerk_m_per_s3 = 50.0
)";

}  // namespace vmsim::test
