// render_part's category colours (tools.png: which tool cut where). Reference: Okabe and Ito's published palette
// ("Color Universal Design": orange #E69F00, sky blue #56B4E9) and the grey of uncut stock, on a flat plate seen from
// above, where the lights change a colour's brightness but not which of red and blue dominates.
#include "core/error.hpp"
#include "render/scene.hpp"
#include "render_test_support.hpp"

#include <gtest/gtest.h>

namespace {

vmsim::core::HeightGrid catc_plate() {
  vmsim::core::HeightGrid g;
  g.x0_mm = 0, g.y0_mm = 0, g.dx_mm = 0.1, g.dy_mm = 0.1;
  g.z_mm = vmsim::core::HeightArray::Constant(101, 201, 0.0);  // 20 x 10 mm
  return g;
}

// Thirds along x: category 0, category 1, none (-1).
TEST(CategoryColours, EachNodeTakesItsCategorysColour) {
  using namespace vmsim::render;
  const vmsim::core::HeightGrid s = catc_plate();
  PartPicture pic;
  pic.width = 480, pic.height = 360;
  pic.view.direction = ViewDirection::Top;
  Eigen::ArrayXXi index(s.ny(), s.nx());
  for (Eigen::Index i = 0; i < s.nx(); ++i) index.col(i).setConstant(s.x(i) < 6.5 ? 0 : s.x(i) < 13.5 ? 1 : -1);
  pic.categories = CategoryColours{index, {"T1 flat D6", "T2 flat D4"}, "uncut stock", "last cut by"};
  const PartImage img = render_part(test::shared_window(), s, nullptr, pic);
  auto colour_at = [&](double x) {
    const Eigen::Vector2d p = img.pixel({x, 5.0, 0.0});
    return img.image.at(static_cast<int>(p.x()), static_cast<int>(p.y()));
  };
  const Rgb8 a = colour_at(3.0), b = colour_at(10.0), c = colour_at(17.0);
  test::keep_if_failed(img.image, "category_colours");
  EXPECT_GT(a[0], a[2] + 60) << "orange: red well above blue";
  EXPECT_GT(a[1], a[2] + 30) << "orange: green above blue";
  EXPECT_GT(b[2], b[0] + 60) << "sky blue: blue well above red";
  EXPECT_LT(std::abs(int(c[0]) - int(c[2])), 12) << "uncut: grey";
  EXPECT_LT(std::abs(int(c[0]) - int(c[1])), 12) << "uncut: grey";
}

TEST(CategoryColours, RefusesAMismatchedGridAndDeviationTogether) {
  using namespace vmsim::render;
  const vmsim::core::HeightGrid s = catc_plate();
  PartPicture pic;
  pic.width = 240, pic.height = 180;
  pic.categories = CategoryColours{Eigen::ArrayXXi::Zero(3, 3), {"T1"}, "", ""};
  EXPECT_THROW(render_part(test::shared_window(), s, nullptr, pic), vmsim::core::Error);
  pic.categories->index = Eigen::ArrayXXi::Zero(s.ny(), s.nx());
  pic.deviation = DeviationColours{};
  EXPECT_THROW(render_part(test::shared_window(), s, &s, pic), vmsim::core::Error);
}

}  // namespace
