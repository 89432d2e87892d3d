#include "app/tiled_run.hpp"

#include "app/mpi_session.hpp"
#include "app/report.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "metrology/marks.hpp"
#include "metrology/x3p.hpp"

#include <fmt/format.h>
#include <mpi.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <ctime>
#include <cstdint>
#include <fstream>
#include <limits>
#include <optional>
#include <utility>
#include <string>
#include <vector>

namespace vmsim::app {

removal::Tile process_tile() {
  if (!mpi_active()) return {};
  return removal::Tile{mpi_rank(), mpi_size()};
}

void quiet_barrier(const char* stage) {
  if (!mpi_active()) return;
  const double limit_s = watchdog_seconds();
  constexpr int kTagArrived = 7201;
  const int rank = mpi_rank(), size = mpi_size();
  // Test hook (tests/app/tiled_run_cli_test.cpp, README "What you can rely on"): this rank stops (SIGSTOP) here.
  if (const char* h = std::getenv("VMSIM_TEST_STOP_RANK"); h && std::atoi(h) == rank && rank != 0) std::raise(SIGSTOP);
  // Each rank tells rank 0 it arrived, so that rank 0 can name the ones that did not.
  int token = rank;
  MPI_Request sent = MPI_REQUEST_NULL;
  if (rank != 0) MPI_Isend(&token, 1, MPI_INT, 0, kTagArrived, MPI_COMM_WORLD, &sent);
  std::vector<char> arrived(static_cast<std::size_t>(size), 0);
  arrived[0] = 1;
  // One note per rank and barrier, taken from each rank in turn: messages from one rank arrive in order, so the first
  // note not yet taken from a rank is this barrier's (a fast rank may already have sent the next barrier's).
  auto receive_arrivals = [&] {
    for (int r = 1; r < size; ++r) {
      if (arrived[static_cast<std::size_t>(r)]) continue;
      int flag = 0;
      MPI_Iprobe(r, kTagArrived, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
      if (!flag) continue;
      int who = 0;
      MPI_Recv(&who, 1, MPI_INT, r, kTagArrived, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      arrived[static_cast<std::size_t>(r)] = 1;
    }
  };
  MPI_Request req;
  MPI_Ibarrier(MPI_COMM_WORLD, &req);
  const auto t0 = std::chrono::steady_clock::now();
  int done = 0;
  while (true) {
    MPI_Test(&req, &done, MPI_STATUS_IGNORE);
    if (rank == 0) receive_arrivals();
    if (done) break;
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (waited > limit_s) {
      std::string missing;
      for (int r = 0; r < size; ++r)
        if (!arrived[static_cast<std::size_t>(r)]) missing += (missing.empty() ? "" : ", ") + std::to_string(r);
      throw core::Error(
          rank == 0
              ? fmt::format("rank 0: rank {} did not reach {} within {:g} s (stopped, or a stalled file system?); "
                            "the job is ended (the limit: --watchdog-s, or VMSIM_WATCHDOG_S)",
                            missing.empty() ? std::string("?") : missing, stage, limit_s)
              : fmt::format("rank {}: waited {:g} s at {} for the other ranks; the job is ended (the limit: "
                            "--watchdog-s, or VMSIM_WATCHDOG_S)",
                            rank, limit_s, stage));
    }
    const timespec pause{0, 1000000};
    nanosleep(&pause, nullptr);
  }
  // Every rank passed the barrier, so every arrival note was sent: rank 0 takes the rest, the others' sends end.
  if (rank == 0) {
    for (int r = 1; r < size; ++r)
      if (!arrived[static_cast<std::size_t>(r)]) {
        int who = 0;
        MPI_Recv(&who, 1, MPI_INT, r, kTagArrived, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      }
  } else {
    MPI_Wait(&sent, MPI_STATUS_IGNORE);
  }
}

namespace {

// A tile's rays packed for one message: per ray its number of intervals, then every interval (lo, hi) in ray order.
struct Packed {
  std::vector<std::uint32_t> counts;
  std::vector<float> values;  // 2 per interval
};

template <class Get>
Packed pack(std::size_t rays, Get&& get) {
  Packed p;
  p.counts.reserve(rays);
  std::vector<removal::Interval> iv;
  for (std::size_t r = 0; r < rays; ++r) {
    get(r, iv);
    p.counts.push_back(static_cast<std::uint32_t>(iv.size()));
    for (const removal::Interval& x : iv) p.values.insert(p.values.end(), {x.lo, x.hi});
  }
  return p;
}

int checked_int(std::size_t n, const char* what) {
  if (n > static_cast<std::size_t>(INT_MAX))
    throw core::Error(
        fmt::format("tiled run: the whole field has {} {}, too many to gather to rank 0 in one MPI "
                    "message; write the tiles instead (vmsim run --tiles-out)",
                    n, what));
  return static_cast<int>(n);
}

// Every rank's packed rays, concatenated in rank order on rank 0 (tiles are consecutive bands, so this is the
// whole list in ray order). Other ranks get empty vectors.
Packed gather_packed(const Packed& mine) {
  const int size = mpi_size(), rank = mpi_rank();
  unsigned long long n[2] = {mine.counts.size(), mine.values.size()};
  std::vector<unsigned long long> all(2 * static_cast<std::size_t>(size));
  MPI_Gather(n, 2, MPI_UNSIGNED_LONG_LONG, all.data(), 2, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
  Packed out;
  std::vector<int> cc(static_cast<std::size_t>(size)), cv(cc.size()), dc(cc.size()), dv(cc.size());
  int bad = 0;
  std::string error;
  if (rank == 0) {
    std::size_t tc = 0, tv = 0;
    for (int r = 0; r < size; ++r) {
      dc[r] = static_cast<int>(std::min<std::size_t>(tc, INT_MAX)),
      dv[r] = static_cast<int>(std::min<std::size_t>(tv, INT_MAX));
      cc[r] = static_cast<int>(std::min<unsigned long long>(all[2 * r], INT_MAX));
      cv[r] = static_cast<int>(std::min<unsigned long long>(all[2 * r + 1], INT_MAX));
      tc += all[2 * r], tv += all[2 * r + 1];
    }
    try {
      checked_int(tc, "rays");
      checked_int(tv, "interval ends");
    } catch (const core::Error& e) {
      bad = 1, error = e.what();
    }
    if (!bad) out.counts.resize(tc), out.values.resize(tv);
  }
  // Every rank learns whether rank 0 can take the message, so no rank is left in a collective.
  MPI_Bcast(&bad, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (bad) throw core::Error(rank == 0 ? error : "tiled run: rank 0 cannot gather the field (see its message)");
  MPI_Gatherv(mine.counts.data(), static_cast<int>(mine.counts.size()), MPI_UINT32_T, out.counts.data(), cc.data(),
              dc.data(), MPI_UINT32_T, 0, MPI_COMM_WORLD);
  MPI_Gatherv(mine.values.data(), static_cast<int>(mine.values.size()), MPI_FLOAT, out.values.data(), cv.data(),
              dv.data(), MPI_FLOAT, 0, MPI_COMM_WORLD);
  return out;
}

template <class Set>
void unpack(const Packed& p, Set&& set) {
  std::vector<removal::Interval> iv;
  std::size_t v = 0;
  for (std::size_t r = 0; r < p.counts.size(); ++r) {
    iv.resize(p.counts[r]);
    for (auto& x : iv) x = removal::Interval{p.values[v], p.values[v + 1]}, v += 2;
    set(r, iv);
  }
}

}  // namespace

std::optional<sim::Field> gather_field(const sim::Field& tile) {
  if (tile.vdb) throw core::Error("tiled run: a level set (method \"vdb\") is not tiled");
  const bool root = mpi_rank() == 0;
  std::optional<sim::Field> whole;
  if (root) {
    // The whole field's geometry, made as a one-process run makes it; its rays come from the tiles.
    whole.emplace();
    sim::Field& w = *whole;
    w.kind = tile.kind, w.region = tile.region, w.spacing_mm = tile.spacing_mm;
    w.needle_point = tile.needle_point, w.needle_normal = tile.needle_normal, w.needle_half = tile.needle_half;
    switch (tile.kind) {
      case core::RemovalSpec::Field::ZMap:
        w.zmap = removal::make_zmap(tile.region, tile.spacing_mm);
        break;
      case core::RemovalSpec::Field::TriDexel:
        w.tri = removal::make_tridexel(tile.region, tile.spacing_mm);
        break;
      case core::RemovalSpec::Field::NBuffer: {
        std::vector<Eigen::Vector3d> o, d;
        std::vector<double> len;
        for (std::size_t k = 0; k < w.needle_point.size(); ++k) {
          o.push_back(w.needle_point[k] - w.needle_half * w.needle_normal[k]);  // as read_needles makes them
          d.push_back(w.needle_normal[k]);
          len.push_back(2 * w.needle_half);
        }
        w.needles = removal::NeedleSet(std::move(o), std::move(d), std::move(len));
        break;
      }
    }
  }
  if (tile.kind == core::RemovalSpec::Field::NBuffer) {
    const Packed all = gather_packed(pack(tile.needles.size(), [&](std::size_t k, std::vector<removal::Interval>& iv) {
      tile.needles.store().get(k, iv);
    }));
    if (root) {
      if (all.counts.size() != whole->needles.size())
        throw core::Error("tiled run: the gathered needles differ in number");
      unpack(all, [&](std::size_t k, const std::vector<removal::Interval>& iv) { whole->needles.store().set(k, iv); });
    }
    return whole;
  }
  const std::vector<const removal::DexelGrid*> mine = tile.grids();
  std::vector<removal::DexelGrid*> dst;
  if (root) dst = whole->grids();
  for (std::size_t g = 0; g < mine.size(); ++g) {
    const removal::DexelGrid& t = *mine[g];
    const Packed all = gather_packed(
        pack(static_cast<std::size_t>(t.nu()) * t.nv(), [&](std::size_t r, std::vector<removal::Interval>& iv) {
          t.intervals(static_cast<int>(r % t.nu()), static_cast<int>(r / t.nu()), iv);
        }));
    if (!root) continue;
    removal::DexelGrid& w = *dst[g];
    if (all.counts.size() != static_cast<std::size_t>(w.nu()) * w.nv())
      throw core::Error("tiled run: the gathered rays differ in number from the whole grid's");
    unpack(all, [&](std::size_t r, const std::vector<removal::Interval>& iv) {
      w.set_intervals(static_cast<int>(r % w.nu()), static_cast<int>(r / w.nu()), iv);
    });
  }
  return whole;
}

std::vector<TileFigures> gather_tile_figures(const TileFigures& mine) {
  constexpr int kN = sizeof(TileFigures) / sizeof(double);
  static_assert(sizeof(TileFigures) == kN * sizeof(double));
  std::vector<TileFigures> all(static_cast<std::size_t>(mpi_size()));
  if (!mpi_active()) {
    all[0] = mine;
    return all;
  }
  MPI_Gather(&mine, kN, MPI_DOUBLE, all.data(), kN, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return all;
}

namespace {

// The tile's reference with one row more on each side where a neighbouring rank holds it (NaN rows where none does):
// the reference's slope (metrology::slope_of) takes central differences across the tile's edges as the whole grid
// has them, so a tile's deviation along the normal is the whole run's, node for node. Bands follow the ranks' order.
core::HeightGrid with_neighbour_rows(const core::HeightGrid& ref) {
  const Eigen::Index nx = ref.nx(), ny = ref.ny();
  core::HeightGrid out = ref;
  out.y0_mm = ref.y0_mm - ref.dy_mm;
  out.z_mm = core::HeightArray::Constant(ny + 2, nx, std::numeric_limits<double>::quiet_NaN());
  out.z_mm.middleRows(1, ny) = ref.z_mm;
  if (!mpi_active() || mpi_size() < 2 || ny == 0) return out;
  constexpr int kTagDown = 7301, kTagUp = 7302;
  const int rank = mpi_rank(), size = mpi_size();
  const int before = rank > 0 ? rank - 1 : MPI_PROC_NULL, after = rank + 1 < size ? rank + 1 : MPI_PROC_NULL;
  std::vector<double> first(static_cast<std::size_t>(nx)), last(first.size()), above(first.size(), NAN),
      below(first.size(), NAN);
  for (Eigen::Index i = 0; i < nx; ++i) first[i] = ref.z_mm(0, i), last[i] = ref.z_mm(ny - 1, i);
  const int n = static_cast<int>(nx);
  MPI_Sendrecv(last.data(), n, MPI_DOUBLE, after, kTagDown, above.data(), n, MPI_DOUBLE, before, kTagDown,
               MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  MPI_Sendrecv(first.data(), n, MPI_DOUBLE, before, kTagUp, below.data(), n, MPI_DOUBLE, after, kTagUp, MPI_COMM_WORLD,
               MPI_STATUS_IGNORE);
  for (Eigen::Index i = 0; i < nx; ++i) out.z_mm(0, i) = above[i], out.z_mm(ny + 1, i) = below[i];
  return out;
}

// The reference's slope on this tile's rows, taken with the neighbours' edge rows.
metrology::Slope tile_slope(const core::HeightGrid& ref) {
  const metrology::Slope wide = metrology::slope_of(with_neighbour_rows(ref));
  metrology::Slope slope{ref, ref};
  slope.slope_rad.z_mm = wide.slope_rad.z_mm.middleRows(1, ref.ny());
  slope.normal_factor.z_mm = wide.normal_factor.z_mm.middleRows(1, ref.ny());
  return slope;
}

}  // namespace

TileFiles write_tile(const std::filesystem::path& dir, const std::string& job_name, const sim::Field& field,
                     const sim::Field* reference) {
  if (field.vdb || field.kind == core::RemovalSpec::Field::NBuffer)
    throw core::Error("--tiles-out writes each tile's height grid: it needs a z-map or tri-dexel field");
  const core::HeightGrid s = sim::surface_of(field);
  // Every rank takes part in the exchange of edge rows before anything can fail on its own (a tile not written).
  std::optional<core::HeightGrid> ref;
  std::optional<metrology::Slope> slope;
  if (reference) {
    quiet_barrier("the exchange of the tiles' edge rows");
    ref = sim::surface_of(*reference);
    slope = tile_slope(*ref);
  }
  const removal::DexelGrid& g = field.kind == core::RemovalSpec::Field::TriDexel ? field.tri.z : field.zmap;
  TileFiles t;
  const int rank = mpi_rank();
  t.surface = fmt::format("tiles/surface_{:04d}.x3p", rank);
  t.first_row = g.v_first(), t.rows = g.nv(), t.nx = g.nu();
  t.x0_mm = s.x0_mm, t.y0_mm = s.y0_mm, t.x1_mm = s.x(s.nx() - 1), t.y1_mm = s.y(s.ny() - 1);
  core::create_result_subdir(dir / "tiles");
  // Test hook (tests/app/tiled_run_cli_test.cpp, README "What you can rely on"): this rank's tile cannot be written.
  // (The output directory is a fresh staging directory, so no obstacle can be planted in it beforehand.)
  if (const char* h = std::getenv("VMSIM_TEST_FAIL_TILE"); h && std::atoi(h) == rank)
    throw core::Error((dir / t.surface).string() + ": cannot write the tile (test hook VMSIM_TEST_FAIL_TILE)");
  metrology::X3pWriteOptions x3p;
  x3p.version = std::string("vmsim ") + VMSIM_VERSION;
  x3p.comment = fmt::format("predicted surface of job {}, tile {} of {} (rows {} to {})", job_name, rank, mpi_size(),
                            t.first_row, t.first_row + t.rows - 1);
  metrology::write_x3p(dir / t.surface, s, x3p);
  if (reference) {
    // Along the reference's normal, as the whole run's deviation (sim/run.cpp).
    const core::HeightGrid dev = metrology::normal_deviation(metrology::deviation(s, *ref), *slope);
    t.deviation = fmt::format("tiles/deviation_{:04d}.x3p", rank);
    x3p.comment = fmt::format(
        "deviation of job {}, tile {} of {}: predicted - reference along the reference's normal "
        "(negative: overcut)",
        job_name, rank, mpi_size());
    metrology::write_x3p(dir / t.deviation, dev, x3p);
  }
  return t;
}

void write_tile_manifest(const std::filesystem::path& dir, const std::string& job_name, const sim::Field& field,
                         const TileFiles& mine) {
  // Every rank's entry to rank 0: the numbers in one message, the names rebuilt from the rank (same format).
  const double nums[7] = {
      double(mine.first_row), double(mine.rows), double(mine.nx), mine.x0_mm, mine.y0_mm, mine.x1_mm, mine.y1_mm};
  const int size = mpi_size();
  std::vector<double> all(7 * static_cast<std::size_t>(size));
  if (mpi_active())
    MPI_Gather(nums, 7, MPI_DOUBLE, all.data(), 7, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  else
    std::copy(nums, nums + 7, all.begin());
  if (mpi_rank() != 0) return;
  const removal::DexelGrid& g = field.kind == core::RemovalSpec::Field::TriDexel ? field.tri.z : field.zmap;
  nlohmann::json tiles = nlohmann::json::array();
  for (int r = 0; r < size; ++r) {
    const double* n = &all[7 * static_cast<std::size_t>(r)];
    nlohmann::json t = {{"rank", r},
                        {"surface", fmt::format("tiles/surface_{:04d}.x3p", r)},
                        {"first_row", static_cast<int>(n[0])},
                        {"nx", static_cast<int>(n[2])},
                        {"ny", static_cast<int>(n[1])},
                        {"x_min_mm", n[3]},
                        {"y_min_mm", n[4]},
                        {"x_max_mm", n[5]},
                        {"y_max_mm", n[6]}};
    if (!mine.deviation.empty()) t["deviation"] = fmt::format("tiles/deviation_{:04d}.x3p", r);
    tiles.push_back(t);
  }
  const int ny_total =
      static_cast<int>(all[7 * static_cast<std::size_t>(size - 1)] + all[7 * static_cast<std::size_t>(size - 1) + 1]);
  nlohmann::json m = {{"job", job_name},
                      {"split", "rows: bands in y, each tile a whole number of dexel rows along x"},
                      {"grid",
                       {{"x0_mm", g.origin().x()},
                        {"y0_mm", g.origin().y()},
                        {"dx_mm", g.du()},
                        {"dy_mm", g.dv()},
                        {"nx", g.nu()},
                        {"ny", ny_total}}},
                      {"tiles", tiles}};
  write_report(dir / "tiles.json", m);
}

}  // namespace vmsim::app
