#pragma once
// Pictures of machined parts: the predicted surface under a raking light so that marks of a few um show, plain
// (machined metal) or coloured by its signed deviation from a reference (diverging map, symmetric limits, scale bar
// in um, optional iso-deviation lines). Part coordinates are the workpiece frame of the job, in mm, z up.
#include "core/height_grid.hpp"
#include "core/mesh.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace vmsim::render {

enum class ViewDirection {
  Isometric,  // from above the front-left corner (azimuth -120 deg, elevation 35 deg), perspective
  Top,        // straight down, +Y up in the picture, parallel projection: a map with a true scale
  AlongPath,  // from behind the cutting direction and a little to its left, 25 deg above the part, perspective
};

// A rectangle of the part in part coordinates (mm).
struct Region {
  double x_min_mm = 0, x_max_mm = 0, y_min_mm = 0, y_max_mm = 0;
};

struct View {
  ViewDirection direction = ViewDirection::Isometric;
  // Zoom: only this part of the part is drawn (cut out of it) and framed. Whole part when empty.
  std::optional<Region> region;
  double path_direction_deg = 0.0;  // AlongPath: cutting direction in the XY plane (0 = +X, 90 = +Y)
  // z drawn as z_min + exaggeration * (z - z_min), z_min the lowest point drawn: the relief of flat scans becomes
  // visible. Applies to height grids and meshes alike; 1 draws the part true to scale.
  double vertical_exaggeration = 1.0;
  // Height grids with a deviation grid: the surface drawn as surface + (magnification - 1) * deviation, i.e. its
  // departure from the reference magnified while the part's form stays true (a mark of 5 um on a curved fillet
  // shows at x 40 where exaggerating all of z would distort the fillet itself). 1 draws the true surface.
  double mark_magnification = 1.0;
};

// The key light: a directional light from low above the part (raking), plus a weak light from the camera so that
// faces turned away from it stay legible.
struct Lighting {
  double elevation_deg = 15.0;  // the key light's height above the XY plane
  // Where the key light comes from, in the XY plane relative to the camera's horizontal viewing direction:
  // 0 from behind the camera, 90 from the camera's right, -90 from its left, 180 against the camera.
  double azimuth_deg = -45.0;
};

struct DeviationColours {
  double limit_mm = 0.0;  // the map spans [-limit, +limit]; 0: symmetric_limit(|deviation|, 1 um)
  int isolines = 0;       // iso-deviation lines on each side of zero at multiples of limit / (isolines + 1)
  bool lit = true;        // shaded by the lights (a 3-D look) or flat, every pixel exactly its map colour
  std::string reference;  // what the deviation is from, for the scale's caption (e.g. "the same pass at 0.1 m/min")
};

// Colour by category (e.g. which tool last cut each node): height grids only. `index` has the surface's shape
// (ny x nx, like z_mm); a node's category k >= 0 takes the k-th colour of a qualitative palette (Okabe and Ito's,
// which colour-blind readers tell apart), -1 the grey of uncut stock. The legend on the right names them.
struct CategoryColours {
  Eigen::ArrayXXi index;
  std::vector<std::string> names;  // legend entry of category k
  std::string none_name;           // legend entry of -1 (omitted when empty)
  std::string title;               // above the legend
};

struct PartPicture {
  int width = 1600, height = 1200;
  std::vector<std::string> caption;  // lines drawn at the top left; the first one larger
  View view;
  Lighting light;
  // Colour by deviation (the grid given with the surface, or the mesh's per-vertex array); plain metal when empty.
  std::optional<DeviationColours> deviation;
  // Colour by category instead (not together with deviation).
  std::optional<CategoryColours> categories;
  // Edges of the 3-D views (Isometric, AlongPath). Top maps are never smoothed: every pixel stays exactly its map
  // colour.
  Antialiasing antialiasing = Antialiasing::Fxaa;
  // Height grids: draw every node. By default a grid finer than about one node per pixel of the picture's larger
  // side is drawn at every k-th node (k the smallest that fits), which the picture cannot tell apart.
  bool full_resolution = false;
  // Flat (unlit) Top maps of a height grid without holes: each pixel's colour computed on the CPU from the deviation
  // interpolated at the pixel's centre over the same two triangles per cell the triangles would be drawn with (so
  // the same colour of the same table), drawn as one image under the iso-lines; a few ms instead of rasterising a
  // triangle or two per pixel. False draws the triangles (as do lit maps and grids with holes).
  bool map_as_image = true;
};

struct PartImage {
  Image image;
  double limit_mm = 0.0;  // the colour limits used (0 for plain pictures)
  // Where a point of the part (part coordinates, mm, before the vertical exaggeration; with a mark magnification,
  // give the magnified z) lands in the image: (x, y) in pixels from the top-left corner of the image (pixel (i, j)
  // covers [i, i+1) x [j, j+1)).
  Eigen::Vector2d pixel(const Eigen::Vector3d& p_mm) const;

  // Set by the renderer: world (drawn) coordinates to normalized device coordinates, the scene's viewport in image
  // pixels (left, top, width, height), and the exaggeration applied about z_base_mm.
  Eigen::Matrix4d world_to_ndc = Eigen::Matrix4d::Identity();
  double viewport_px[4] = {0, 0, 0, 0};
  double exaggeration = 1.0, z_base_mm = 0.0;
};

// A height grid drawn as a surface with side walls down to a base under its lowest point (a solid block). NaN
// nodes leave holes. `deviation` (same grid: size, origin and spacing; may be null for plain pictures without
// mark magnification) colours it when picture.deviation is set.
// Throws core::Error for an empty grid, a mismatched deviation grid or options out of range.
PartImage render_part(Window& window, const core::HeightGrid& surface, const core::HeightGrid* deviation,
                      const PartPicture& picture);

// A triangle mesh (e.g. part.vtp's). Its per-vertex array `deviation_array` (mm) colours it when
// picture.deviation is set. Sharp edges (more than 40 deg) stay sharp in the shading.
PartImage render_part(Window& window, const core::TriangleMesh& mesh, const PartPicture& picture,
                      const std::string& deviation_array = "deviation_mm");

// Zoom on a mark: a region of 2 half_extent around (x, y), widened to the aspect of a width x height picture, then
// slid inside `bounds` where it fits and clipped to them where it does not.
Region region_around(double x_mm, double y_mm, double half_extent_mm, const Region& bounds, int width, int height);

}  // namespace vmsim::render
