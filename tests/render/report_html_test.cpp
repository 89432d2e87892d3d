// report.html from crafted reports: what a page must never do (let a job name or a message become markup, link a
// picture that is not a PNG, hide a key of the report) and what it must say. References: the HTML specification's
// character references for text and attribute values (& < > " '), RFC 3986 percent-encoding for the links, the PNG
// specification's IHDR chunk for the pictures' sizes (the files here are written by render::write_png). Whole pages
// of real runs are validated and opened in Chromium by the app tests (tests/app/check_report_html.py,
// report_html_browser_test.py).
#include "render/report_html.hpp"
#include "render/image.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vmsim::render::report_html;

class Dir {
 public:
  Dir() {
    std::random_device rd;
    path_ = fs::temp_directory_path() / ("vmsim_html_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~Dir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write_text(const fs::path& p, const std::string& s) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << s;
}

void write_picture(const fs::path& p, int w, int h) {
  fs::create_directories(p.parent_path());
  vmsim::render::Image img;
  img.width = w;
  img.height = h;
  img.rgb.assign(static_cast<std::size_t>(w * h * 3), 128);
  vmsim::render::write_png(p, img);
}

json run_report() {
  return json::parse(R"({
    "vmsim": "0.1.0", "command": "run", "job": "part",
    "inputs": {"job": {"path": "/p/job.toml", "sha256": "ab12"}},
    "marks": [{"depth_mm": 0.0191, "kind": "undercut", "x_mm": 85.95, "y_mm": 4.95, "x_extent_mm": 5.35,
               "y_extent_mm": 1.25, "area_mm2": 6.67}],
    "surface": {"deviation_min_mm": -1.5e-05, "deviation_max_mm": 0.0191},
    "interpolation": {"cycle_time_s": 4.883},
    "timings_s": {"total": 17.3}
  })");
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST(ReportHtml, EveryStringFromTheReportIsText) {
  Dir d;
  json r = run_report();
  r["job"] = "<script>alert(\"x\")</script> & 'y'";
  r["inputs"]["job"]["path"] = "/p/\"><img src=x onerror=alert(1)>.toml";
  r["warnings"] = {"<b>bold</b> claim"};
  r["new_key"] = "</table></section>";
  r["marks"][0]["kind"] = "<i>undercut</i>";
  const std::string page = report_html(r, d.path());
  EXPECT_EQ(page.find("<script"), std::string::npos);
  EXPECT_EQ(page.find("<img src=x"), std::string::npos);
  EXPECT_EQ(page.find("<b>bold"), std::string::npos);
  EXPECT_EQ(page.find("<i>undercut"), std::string::npos);
  EXPECT_EQ(count(page, "</table></section>"), 0u);
  EXPECT_NE(page.find("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &#39;y&#39;"), std::string::npos);
  EXPECT_NE(page.find("&quot;&gt;&lt;img src=x onerror=alert(1)&gt;.toml"), std::string::npos);
  EXPECT_NE(page.find("&lt;b&gt;bold&lt;/b&gt; claim"), std::string::npos);
  EXPECT_NE(page.find("&lt;/table&gt;&lt;/section&gt;"), std::string::npos);
}

TEST(ReportHtml, KeysNoSectionShowsAreListedUnderAllFigures) {
  Dir d;
  json r = run_report();
  r["new_module"] = {{"depth_um", 2.5}, {"note", "seen"}, {"per_axis", {{"X", {{"peak_mm", 0.125}}}}}};
  r["list_of_numbers"] = {1.5, 2.5e-07};
  const std::string page = report_html(r, d.path());
  const auto all = page.find("<section id=\"all\">");
  ASSERT_NE(all, std::string::npos);
  const std::string rest = page.substr(all);
  EXPECT_NE(rest.find("new module › depth um"), std::string::npos);
  EXPECT_NE(rest.find("data-value=\"2.5\""), std::string::npos);
  EXPECT_NE(rest.find("seen"), std::string::npos);
  EXPECT_NE(rest.find("data-value=\"0.125\""), std::string::npos);
  EXPECT_NE(rest.find("data-value=\"2.5e-07\""), std::string::npos);
  // What a section shows is not listed again: the marks are in their table, not under All figures.
  EXPECT_EQ(rest.find("depth_mm"), std::string::npos);
  EXPECT_EQ(rest.find("marks ›"), std::string::npos);
}

TEST(ReportHtml, TheMarksTableAndKeyFiguresCarryTheReportsValues) {
  Dir d;
  const std::string page = report_html(run_report(), d.path());
  const auto marks = page.find("<section id=\"marks\">");
  ASSERT_NE(marks, std::string::npos);
  // 0.0191 mm = 19.10 um, shown with the report's own value beside it.
  EXPECT_NE(page.find("<span data-value=\"0.0191\">19.10 µm</span>", marks), std::string::npos);
  EXPECT_NE(page.find("<span data-value=\"85.95\">85.950 mm</span>", marks), std::string::npos);
  EXPECT_NE(page.find("<span data-value=\"4.883\">4.88 s</span>"), std::string::npos);
  // The colour limits the pictures use for a largest |deviation| of 19.1 um: rounded up to 20 (render/colormap).
  EXPECT_NE(page.find("Colour limits ±20 µm"), std::string::npos);
}

TEST(ReportHtml, PicturesAreLinkedOnlyWhenTheyAreReadablePngFiles) {
  Dir d;
  write_picture(d.path() / "images" / "part.png", 40, 30);
  write_picture(d.path() / "images" / "new_chart.png", 20, 10);
  write_text(d.path() / "images" / "broken.png", "not a PNG file");
  write_text(d.path() / "images" / "notes.txt", "text");
  const std::string page = report_html(run_report(), d.path());
  EXPECT_NE(page.find("<img src=\"images/part.png\" width=\"40\" height=\"30\""), std::string::npos);
  EXPECT_EQ(page.find("src=\"images/broken.png\""), std::string::npos);
  EXPECT_EQ(page.find("notes.txt"), std::string::npos);
  // A picture no section knows is still shown, under "Other pictures".
  const auto other = page.find("<section id=\"other-pictures\">");
  ASSERT_NE(other, std::string::npos);
  EXPECT_NE(page.find("<img src=\"images/new_chart.png\" width=\"20\" height=\"10\"", other), std::string::npos);
  // Each picture once.
  EXPECT_EQ(count(page, "<img src=\"images/part.png\""), 1u);
}

TEST(ReportHtml, APageWithoutPicturesSaysWhy) {
  Dir d;
  json r = run_report();
  r["render_error"] = "no EGL display: <driver> missing";
  std::string page = report_html(r, d.path());
  EXPECT_NE(page.find("The pictures could not be drawn: no EGL display: &lt;driver&gt; missing"), std::string::npos);
  EXPECT_EQ(page.find("<img"), std::string::npos);
  EXPECT_NE(page.find("<span data-value=\"0.0191\">19.10 µm</span>"), std::string::npos);  // the rest is there
  r.erase("render_error");
  page = report_html(r, d.path());
  EXPECT_NE(page.find("the command was run with --no-render"), std::string::npos);
  // A command that draws no pictures (measure): nothing to explain.
  r["command"] = "measure";
  page = report_html(r, d.path());
  EXPECT_EQ(page.find("--no-render"), std::string::npos);
}

TEST(ReportHtml, VerdictAndWarningsWhenTheReportHasThem) {
  Dir d;
  json r = run_report();
  std::string page = report_html(r, d.path());
  EXPECT_EQ(page.find("class=\"verdict"), std::string::npos);
  EXPECT_EQ(page.find("class=\"warnings\""), std::string::npos);
  r["verdict"] = {{"status", "fail"}, {"text", "mark deeper than the tolerance"}};
  r["warnings"] = {"the reference is coarse", {{"message", "feed clipped"}}};
  page = report_html(r, d.path());
  EXPECT_NE(page.find("class=\"verdict bad\""), std::string::npos);
  EXPECT_NE(page.find("mark deeper than the tolerance"), std::string::npos);
  EXPECT_NE(page.find("<li>the reference is coarse</li>"), std::string::npos);
  EXPECT_NE(page.find("<li>feed clipped</li>"), std::string::npos);
  r["verdict"] = "acceptable";
  EXPECT_NE(report_html(r, d.path()).find("<div class=\"verdict\">acceptable</div>"), std::string::npos);
}

TEST(ReportHtml, LinksStayInTheFolderAndArePercentEncoded) {
  Dir d;
  json r = run_report();
  write_text(d.path() / "my file#1.csv", "x");
  r["files"] = {"my file#1.csv", "gone.csv", "/etc/passwd", "../outside.csv"};
  const std::string page = report_html(r, d.path());
  EXPECT_NE(page.find("<a href=\"my%20file%231.csv\">my file#1.csv</a>"), std::string::npos);
  EXPECT_NE(page.find("gone.csv (not in this folder)"), std::string::npos);
  EXPECT_EQ(page.find("href=\"/etc/passwd\""), std::string::npos);
  EXPECT_EQ(page.find("href=\"../outside.csv\""), std::string::npos);
}

json study_report() {
  return json::parse(R"({
    "vmsim": "0.1.0", "command": "study", "study": "kv", "ranks": 1,
    "summary": {"variations": 2, "ok": 1, "failed": 1, "pending": 0},
    "variations": [
      {"variation": 1, "name": "a", "dir": "variations/001", "status": "ok", "cpu_s": 1.0, "wall_s": 1.1, "rank": 0,
       "overrides": [{"key": "removal.spacing_mm", "value": "0.1", "where": "[common]"},
                     {"key": "feed_scale", "value": "0.5", "where": "[grid]"}],
       "figures": {"marks": 1, "mark_depth_mm": 0.052, "mark_kind": "undercut"}},
      {"variation": 2, "name": "b", "dir": "variations/002", "status": "failed", "cpu_s": 0.1, "wall_s": 0.1, "rank": 0,
       "error": "study.toml: variation 2 (b): bad <key>",
       "overrides": [{"key": "removal.spacing_mm", "value": "0.1", "where": "[common]"},
                     {"key": "feed_scale", "value": "1.0", "where": "[grid]"}],
       "figures": {"marks": 0}}],
    "timings_s": {"total": 2.0}
  })");
}

TEST(ReportHtml, StudyRowsLinkTheVariationsPagesThatExist) {
  Dir d;
  write_text(d.path() / "variations" / "001" / "report.html", "<!DOCTYPE html>");
  const json s = study_report();
  const std::string page = report_html(s, d.path());
  EXPECT_NE(page.find("<a href=\"variations/001/report.html\""), std::string::npos);
  EXPECT_EQ(page.find("variations/002/report.html"), std::string::npos);
  EXPECT_NE(page.find("<span data-value=\"0.052\">52.00 µm</span>"), std::string::npos);
  EXPECT_NE(page.find("bad &lt;key&gt;"), std::string::npos);
  // The key every variation sets alike is said once; the varied one is a column.
  EXPECT_NE(page.find("Every variation sets <code title=\"[common]\">removal.spacing_mm = 0.1</code>"),
            std::string::npos);
  EXPECT_NE(page.find("<th><code>feed_scale</code></th>"), std::string::npos);
}

// Every entry of a report replaced in turn by a value of another type (a string, a number, a list, null): the page is
// still made (what does not fit is shown as it is), never an exception that would fail the command after its
// report.json is written.
void mutate_each(json& root, json& node, const fs::path& dir, const std::string& where, int& pages) {
  const json saved = node;
  for (const json& other : {json("x<y>"), json(1.5), json::array({1, "a"}), json(nullptr)}) {
    node = other;
    std::string page;
    EXPECT_NO_THROW(page = report_html(root, dir)) << where << " = " << other.dump();
    EXPECT_EQ(page.rfind("<!DOCTYPE html>", 0), 0u) << where;
    ++pages;
  }
  node = saved;
  if (node.is_object())
    for (auto& [k, v] : node.items()) mutate_each(root, v, dir, where + "/" + k, pages);
  else if (node.is_array())
    for (auto& v : node) mutate_each(root, v, dir, where + "/[]", pages);
}

TEST(ReportHtml, AReportOfAnyShapeStillGivesAPage) {
  Dir d;
  write_picture(d.path() / "images" / "part.png", 8, 6);
  int pages = 0;
  for (json r : {run_report(), study_report()}) {
    r["verdict"] = {{"status", "ok"}};
    r["warnings"] = {"w"};
    for (const char* command : {"run", "compare", "oga", "plan-feed", "compensate", "study", "motion"}) {
      r["command"] = command;
      mutate_each(r, r, d.path(), command, pages);
    }
  }
  EXPECT_GT(pages, 1000);
}
