// The memory model of a run (sim/memory_plan.hpp), per process and per rank, with advice.
#include "sim/memory_plan.hpp"

#include "sim/pipeline.hpp"
#include "sim/report.hpp"
#include "core/memory.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "removal/cut.hpp"
#include "removal/dexel_grid.hpp"
#include "removal/fields.hpp"
#include "removal/vdb_part.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace vmsim::sim {

double motion_bytes_per_setpoint(int axes, bool turning) {
  return 8.0 * axes + 20 + 64.0 * axes + 60 + 48 + (turning ? 24 : 0) + 8.0 * (4 * axes + 6);
}

double streamed_motion_bytes_per_setpoint(int axes, bool turning) {
  const double setpoints = 8.0 * axes + 20, turn = turning ? 24 : 0;
  // The interpolator writes the setpoints as it samples (motion/interp.cpp): its own arrays are the path parameter
  // per sample, raw and filtered (16 B). The drives run without the path length (8 B: a run never reads it).
  const double interpolation = setpoints + 16;
  const double blocks = setpoints - 8 + 48 + turn + 24;  // track (tip, velocity, axis) and commanded tip
  // Move index, tip, axis, then the command merged while it is still held (24 + 36 B); after it is released, the
  // merged path's normals and the result (16 B) take less.
  const double contour = 4 + 24 + turn + 24 + 36;
  return std::max({interpolation, blocks, contour});
}

namespace {

constexpr double kBaseBytes = 70e6;  // the process: code and libraries (bench/README.md, measured)
constexpr double kSweepBytes = sizeof(removal::SweptTool);
// removal::cut's index of one call (all of a grid's sweeps at once): each sweep's footprint and its extent along the
// rays, and its entry in a row block's bin (a few blocks for a tall one: two ints counted).
constexpr double kCutIndexBytes = sizeof(removal::Footprint) + 2 * sizeof(double) + 2 * sizeof(int);
constexpr double kZmapOutputBytesPerNode = 136;  // 3 height grids (24) + part mesh with deviation (56) + writer (56)
constexpr double kGridsBytesPerNode = 24;        // the 3 height grids without the part mesh
constexpr double kTileOutputBytesPerNode = 24;   // a tile's surface, reference and deviation grids

// The field a job starts from, as geometry: the first job of its stock chain makes it.
struct FieldShape {
  core::RemovalSpec::Field kind = core::RemovalSpec::Field::ZMap;
  bool vdb = false;
  double spacing_mm = 0, voxel_mm = 0;
  removal::Box region;
  double stock_area_mm2 = 0;
  std::vector<removal::GridShape> grids;
  std::size_t needles = 0;
};

// The needles' rows as sim::read_needles reads them (core/csv), without parsing their numbers.
std::size_t count_needles(const std::filesystem::path& file) {
  core::CsvReader in(file, core::CsvReader::Header::Optional);
  std::size_t n = 0;
  while (in.next()) ++n;
  return n;
}

FieldShape shape_of(const core::Job& job, int depth = 0) {
  if (depth > 32) throw core::Error(job.file.string() + ": the stock jobs form a cycle");
  if (job.stock.kind == core::StockSpec::Kind::Job) return shape_of(core::load_job(job.stock.job_file), depth + 1);
  FieldShape s;
  s.kind = job.removal.field;
  s.vdb = job.removal.method == core::RemovalSpec::Method::Vdb;
  s.spacing_mm = job.removal.spacing_mm;
  s.voxel_mm = job.removal.voxel_mm;
  if (job.stock.kind == core::StockSpec::Kind::Mesh || job.stock.kind == core::StockSpec::Kind::Box) {
    const std::optional<removal::Box> box = stock_box(job);
    if (!box) throw core::Error(job.stock.mesh_file.string() + ": the stock mesh has no vertices");
    s.region = *box;
  } else {
    throw core::Error(job.file.string() + ": [stock] is required to remove material (box, stl or job)");
  }
  const Eigen::Vector3d e = s.region.hi - s.region.lo;
  s.stock_area_mm2 = 2 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
  if (s.kind == core::RemovalSpec::Field::NBuffer) {
    s.needles = count_needles(job.removal.needles_file);
  } else {
    s.grids = removal::field_shape(s.region, s.spacing_mm, s.kind == core::RemovalSpec::Field::TriDexel);
  }
  return s;
}

// Bytes of a tile's field before any cut splits a ray, and its rays.
struct TileSize {
  double rays = 0, bytes = 0;
  std::vector<int> rows;
};
TileSize tile_size(const FieldShape& s, const removal::Tile& t) {
  TileSize z;
  if (s.kind == core::RemovalSpec::Field::NBuffer) {
    const std::size_t block = removal::NeedleSet::kBlock, n = s.needles;
    std::size_t k0 = 0, k1 = n;
    if (!t.whole()) {
      const auto [b0, b1] = removal::tile_rows(static_cast<int>((n + block - 1) / block), t);
      k0 = static_cast<std::size_t>(b0) * block, k1 = std::min(n, static_cast<std::size_t>(b1) * block);
    }
    z.rays = double(k1 - k0);
    z.bytes = double(removal::IntervalStore::initial_bytes(k1 - k0, block));
    z.rows.push_back(static_cast<int>(k1 - k0));
    return z;
  }
  for (const auto& g : s.grids) {
    const auto [first, end] = removal::tile_rows(g.nv, t);
    const std::size_t rays = static_cast<std::size_t>(g.nu) * static_cast<std::size_t>(end - first);
    z.rays += double(rays);
    z.bytes += double(removal::IntervalStore::initial_bytes(rays, static_cast<std::size_t>(g.nu)));
    z.rows.push_back(end - first);
  }
  return z;
}

// Height-grid nodes of a field's surface (z-map, or the tri-dexel's z grid), for `rows` of them.
double surface_nodes(const FieldShape& s, int rows) {
  if (s.kind == core::RemovalSpec::Field::NBuffer) return 0;
  return double(s.grids.back().nu) * rows;
}

double motion_bytes(const PlannedMotion* m, int axes) {
  if (!m) return 0;
  return m->samples * (m->streamed ? streamed_motion_bytes_per_setpoint(axes, m->turning)
                                   : motion_bytes_per_setpoint(axes, m->turning));
}
double sweep_count(const PlannedMotion* m) { return m ? double(m->sweeps.size()) : 0.0; }

}  // namespace

nlohmann::json plan_memory(const core::Job& job, const MemoryPlanOptions& options, core::Progress& progress,
                           PlannedMotions* motions_out) {
  const int ranks = options.ranks;
  if (ranks < 1) throw core::Error("--ranks: expected a whole number >= 1");
  const FieldShape shape = shape_of(job);

  // The motion and the reference (sim/plan_motion.hpp): exact sample and sweep counts.
  PlannedMotions local;
  PlannedMotions& motions = motions_out ? *motions_out : local;
  motions = plan_motions(job, options.feed_scale, progress);
  const PlannedMotion* own = &motions.own;
  const PlannedMotion* refm = motions.reference ? &*motions.reference : nullptr;
  std::optional<FieldShape> ref_shape;
  switch (job.reference.kind) {
    case core::ReferenceSpec::Kind::Feed:
    case core::ReferenceSpec::Kind::Program:
    case core::ReferenceSpec::Kind::Stock:
      ref_shape = shape;
      break;
    case core::ReferenceSpec::Kind::Job:
      ref_shape = shape_of(core::load_job(job.reference.job_file));
      break;
    case core::ReferenceSpec::Kind::None:
      break;
  }
  const int axes = static_cast<int>(job.machine.axes.size());
  const double b_motion = motion_bytes(own, axes) + motion_bytes(refm, axes);
  const double b_sweeps = kSweepBytes * (sweep_count(own) + sweep_count(refm)) +
                          kCutIndexBytes * std::max(sweep_count(own), sweep_count(refm));

  // Outputs of the whole part (one process, or rank 0 when gathered).
  double b_outputs_whole = 0;
  if (shape.vdb || shape.kind == core::RemovalSpec::Field::TriDexel) {
    const double h = shape.vdb ? shape.voxel_mm : shape.spacing_mm;
    // Twice the stock's area at the worst orientation (projections sqrt(3) times the area): the plan's upper bound.
    const removal::SurfaceArea sa{2 * shape.stock_area_mm2, 2 * std::sqrt(3.0) * shape.stock_area_mm2};
    b_outputs_whole =
        2 * (removal::estimate_level_set_bytes(sa, h) + removal::estimate_mesh_bytes(2 * shape.stock_area_mm2, h));
  }
  if (shape.kind != core::RemovalSpec::Field::NBuffer && !shape.vdb) {
    // The part mesh is made only when written (sim/run.hpp): not for [outputs] part_mesh = "none", nor by default
    // for a grid of more than large_grid_nodes (sim/run_outputs.cpp's rule); then the three grids alone.
    const double nodes = surface_nodes(shape, shape.grids.back().nv);
    const core::OutputsSpec& o = job.outputs;
    const bool mesh = o.part_mesh == core::OutputsSpec::Mesh::Auto ? nodes <= o.large_grid_nodes
                                                                   : o.part_mesh != core::OutputsSpec::Mesh::None;
    b_outputs_whole += (mesh ? kZmapOutputBytesPerNode : kGridsBytesPerNode) * nodes;
  }
  if (shape.kind == core::RemovalSpec::Field::NBuffer) b_outputs_whole += 200.0 * double(shape.needles);  // CSV rows

  const TileSize whole = tile_size(shape, {});
  const TileSize ref_whole = ref_shape ? tile_size(*ref_shape, {}) : TileSize{};
  // Copies a run holds: the field, the stock it started from, the reference.
  auto per_process = [&](const TileSize& t, const TileSize& rt) { return 2 * t.bytes + rt.bytes; };

  nlohmann::json plan = report_header("run --plan", job);
  nlohmann::json grids = nlohmann::json::array();
  for (const auto& g : shape.grids) grids.push_back({{"nu", g.nu}, {"nv", g.nv}, {"rays", double(g.nu) * g.nv}});
  plan["field"] = {{"kind", shape.kind == core::RemovalSpec::Field::ZMap       ? "zmap"
                            : shape.kind == core::RemovalSpec::Field::TriDexel ? "tridexel"
                                                                               : "nbuffer"},
                   {"method", shape.vdb ? "vdb" : "dexel"},
                   {"spacing_mm", shape.spacing_mm},
                   {"grids", grids},
                   {"rays", whole.rays},
                   {"bytes", whole.bytes}};
  if (ref_shape) plan["reference_field"] = {{"rays", ref_whole.rays}, {"bytes", ref_whole.bytes}};
  plan["motion"] = {{"samples", own->samples},
                    {"sweeps", sweep_count(own)},
                    {"axes", axes},
                    {"reference_samples", refm ? refm->samples : 0.0},
                    {"reference_sweeps", sweep_count(refm)},
                    {"bytes", b_motion},
                    {"sweep_bytes", b_sweeps}};

  const double one = kBaseBytes + per_process(whole, ref_whole) + b_motion + b_sweeps + b_outputs_whole;
  plan["one_process"] = {{"field_bytes", per_process(whole, ref_whole)},
                         {"motion_bytes", b_motion},
                         {"sweep_bytes", b_sweeps},
                         {"output_bytes", b_outputs_whole},
                         {"base_bytes", kBaseBytes},
                         {"total_bytes", one}};
  // The machine this plan runs on: what it has left (core/memory.hpp), and whether one process fits in it.
  const core::AvailableMemory avail = core::available_memory();
  plan["available_memory"] = {{"bytes", std::isfinite(avail.bytes) ? nlohmann::json(avail.bytes) : nlohmann::json()},
                              {"source", avail.source}};
  plan["one_process"]["fits_available_memory"] = one <= avail.bytes;

  // Per rank of a tiled run, gathered to rank 0 and with --tiles-out.
  auto rank_totals = [&](int n, bool tiles_out, nlohmann::json* out) {
    double worst = 0;
    for (int r = 0; r < n; ++r) {
      const removal::Tile t{r, n};
      const TileSize ts = tile_size(shape, t);
      const TileSize rts = ref_shape ? tile_size(*ref_shape, t) : TileSize{};
      double gather = 0, outputs = 0;
      if (n > 1 && !tiles_out && r == 0) {
        double largest = 0;
        for (const auto& g : shape.grids) largest = std::max(largest, double(g.nu) * g.nv);
        if (shape.kind == core::RemovalSpec::Field::NBuffer) largest = double(shape.needles);
        gather = whole.bytes + ref_whole.bytes + 12 * largest;
      }
      if (n == 1 || (!tiles_out && r == 0)) outputs = b_outputs_whole;
      if (tiles_out && !ts.rows.empty()) outputs = kTileOutputBytesPerNode * surface_nodes(shape, ts.rows.back());
      const double total = kBaseBytes + per_process(ts, rts) + b_motion + b_sweeps + gather + outputs;
      worst = std::max(worst, total);
      if (out)
        out->push_back({{"rank", r},
                        {"rows", ts.rows},
                        {"rays", ts.rays},
                        {"field_bytes", per_process(ts, rts)},
                        {"motion_bytes", b_motion},
                        {"sweep_bytes", b_sweeps},
                        {"gather_bytes", gather},
                        {"output_bytes", outputs},
                        {"base_bytes", kBaseBytes},
                        {"total_bytes", total}});
    }
    return worst;
  };
  int max_ranks = 1 << 20;
  if (shape.kind != core::RemovalSpec::Field::NBuffer)
    for (const auto& g : shape.grids) max_ranks = std::min(max_ranks, g.nv);
  else
    max_ranks = static_cast<int>((shape.needles + removal::NeedleSet::kBlock - 1) / removal::NeedleSet::kBlock);
  if (ranks > 1 && shape.vdb) throw core::Error(job.file.string() + ": [removal] method = \"vdb\" does not run tiled");
  if (ranks > max_ranks)
    throw core::Error(
        fmt::format("--ranks {}: the field has {} rows to share; use at most {} ranks", ranks, max_ranks, max_ranks));
  plan["ranks"] = ranks;
  for (const bool tiles_out : {false, true}) {
    if (ranks == 1 && tiles_out) continue;
    nlohmann::json per = nlohmann::json::array();
    const double worst = rank_totals(ranks, tiles_out, &per);
    plan[tiles_out ? "tiles_out" : "gathered"] = {{"per_rank", per}, {"largest_rank_bytes", worst}};
  }

  // Advice for a memory per rank.
  if (options.memory_per_rank_bytes) {
    const double limit = *options.memory_per_rank_bytes;
    if (!(limit > 0)) throw core::Error("--memory-per-rank-gb: expected a positive number");
    nlohmann::json advice;
    auto least = [&](bool tiles_out) -> int {
      for (int n = 1; n <= max_ranks; n = n < 8 ? n + 1 : n + std::max(1, n / 16))
        if (rank_totals(n, tiles_out, nullptr) <= limit) return n;
      return 0;
    };
    const int ng = least(false), nt = least(true);
    advice["memory_per_rank_bytes"] = limit;
    advice["ranks_gathered"] = ng;
    advice["ranks_tiles_out"] = nt;
    // One process at a coarser spacing: field and outputs scale with 1 / spacing^2 (rays on a plane).
    const double fixed = kBaseBytes + b_motion + b_sweeps;
    const double scaled = one - fixed;
    if (limit > fixed && scaled > 0 && !shape.vdb) {
      const double s = shape.spacing_mm * std::sqrt(std::max(1.0, scaled / (limit - fixed)));
      advice["one_process_spacing_mm"] = s;
    }
    plan["advice"] = advice;
  }
  plan["assumptions"] = {
      "field: 8 bytes per ray and 56 per row before cuts split rays (split rays add their intervals)",
      "copies: the field, the stock it starts from, and the reference field are held together",
      "motion, an actual motion (streamed in blocks; the job's, a feed reference's, a stock or reference job's): per "
      "setpoint the largest of 8 a + 20 (setpoints) + 95 "
      "(the interpolator's arrays), 8 a + 20 + 72 (track and commanded tip, while the drives run in blocks) and 136 "
      "(the contour error's), plus 24 for a turning tool axis",
      "motion, other (setpoints, the programmed path, a reference job's or feed reference's actual motion): per "
      "setpoint "
      "8 a + 20 (setpoints) + 64 a (drives) + 60 (contour) + 48 (track) + 8 (4 a + 6) (signals)",
      "sweeps: 96 bytes each, the job's and the reference's, + 56 bytes each of the larger cut's index",
      "outputs: 136 bytes per height-grid node (z-map); tri-dexel and vdb: OpenVDB level set and mesh estimates",
      "base: 70 MB per process (code and libraries)"};
  return plan;
}

}  // namespace vmsim::sim
