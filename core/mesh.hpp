#pragma once
// A triangle mesh of a part, with optional per-vertex scalars (signed deviation from a reference, in mm).
#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::core {

struct TriangleMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> vertices_mm;
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> triangles;  // counter-clockwise seen from outside
  // Named per-vertex scalars, e.g. {"deviation_mm", ...}; each has vertices_mm.rows() entries.
  std::vector<std::pair<std::string, Eigen::VectorXd>> point_data;
};

}  // namespace vmsim::core
