// The synthetic scan's truth file (dentmark.truth/1): what `synth scan --truth` writes
// is read back whole, door pose included, and each malformed field is named.
#include <gtest/gtest.h>

#include <fstream>

#include "../support/temp_dir.h"
#include "dentmark/sim/scan/truth_file.h"

namespace dentmark::sim::scan {
namespace {

std::string write(const ::dentmark::test::TempDir& dir, const std::string& name, const std::string& text) {
  const std::string path = (dir.path() / name).string();
  std::ofstream(path) << text;
  return path;
}

TruthFile example() {
  TruthFile t;
  t.defects.push_back({"dent", {0.1, -0.2, 0.9}, {0.0, 0.6, 0.8}, 0.012, -0.0004});
  t.defects.push_back({"hole", {0.3, 0.1, 0.95}, {0.0, 0.0, 1.0}, 0.008, 0.0});
  t.features.push_back({"crease", {{0.0, 0.0, 0.9}, {0.1, 0.0, 0.9}}, 0.01});
  t.panel_area = 0.84;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.05, -0.02, 0.9);
  t.T_sls_panel = T;
  t.panel_width = 1.1;
  t.panel_height = 0.7;
  t.generator = {{"seed", 7}};
  return t;
}

TEST(TruthFile, WrittenFileReadsBackTheSameTruth) {
  ::dentmark::test::TempDir dir("truth");
  const TruthFile t = example();
  const TruthFile r = read_truth_file(write(dir, "t.json", truth_to_json(t).dump(1)));
  ASSERT_EQ(r.defects.size(), 2u);
  EXPECT_EQ(r.defects[0].defect_class, "dent");
  EXPECT_TRUE(r.defects[0].position.isApprox(t.defects[0].position, 1e-15));
  EXPECT_TRUE(r.defects[0].normal.isApprox(t.defects[0].normal, 1e-15));
  EXPECT_DOUBLE_EQ(r.defects[0].height, -0.0004);
  EXPECT_EQ(r.defects[1].defect_class, "hole");
  ASSERT_EQ(r.features.size(), 1u);
  EXPECT_EQ(r.features[0].points.size(), 2u);
  EXPECT_DOUBLE_EQ(r.panel_area, 0.84);
  ASSERT_TRUE(r.T_sls_panel.has_value());
  EXPECT_TRUE(r.T_sls_panel->matrix().isApprox(t.T_sls_panel->matrix(), 1e-15));
  EXPECT_DOUBLE_EQ(r.panel_width, 1.1);
  EXPECT_EQ(r.generator.value("seed", 0), 7);
}

TEST(TruthFile, WithoutAPoseTheFileHasNone) {
  ::dentmark::test::TempDir dir("truth");
  TruthFile t = example();
  t.T_sls_panel.reset();
  t.generator = nlohmann::json::object();
  EXPECT_FALSE(read_truth_file(write(dir, "t.json", truth_to_json(t).dump())).T_sls_panel.has_value());
}

// Each edit of a good file and the message that must name what is wrong.
TEST(TruthFile, EachMalformedFieldIsNamed) {
  ::dentmark::test::TempDir dir("truth");
  const nlohmann::json good = truth_to_json(example());
  const auto error_of = [&](const std::function<void(nlohmann::json&)>& edit) -> std::string {
    nlohmann::json j = good;
    edit(j);
    try {
      read_truth_file(write(dir, "bad.json", j.dump()));
    } catch (const TruthFileError& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_NE(error_of([](nlohmann::json& j) { j["schema"] = "dentmark.defects/1"; }).find("field schema"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["defects"][1]["class"] = "scratch";
            }).find("field defects[1].class: 'scratch' is not dent, bump or hole"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["defects"][0]["position"] = {1, 2};
            }).find("field defects[0].position: expected [x, y, z]"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["defects"][0]["normal"] = {0, 0, 0};
            }).find("defects[0].normal: zero vector"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["defects"][0].erase("diameter");
            }).find("defects[0].diameter: missing or not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["features"][0]["points"][1] = "x";
            }).find("features[0].points[1]: expected [x, y, z]"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["generator"]["T_sls_panel"][0][0] = 2.0;
            }).find("generator.T_sls_panel: not a rigid transform"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) {
              j["generator"]["panel_size"] = {1.0, -1.0};
            }).find("generator.panel_size"),
            std::string::npos);
  EXPECT_NE(error_of([](nlohmann::json& j) { j.erase("panel_area"); }).find("field.panel_area"),
            std::string::npos);
}

TEST(TruthFile, NotJsonNamesTheByte) {
  ::dentmark::test::TempDir dir("truth");
  try {
    read_truth_file(write(dir, "t.json", "{\"schema\": \"dentmark.truth/1\", \"defects\": [}"));
    FAIL() << "accepted";
  } catch (const TruthFileError& e) {
    EXPECT_NE(std::string(e.what()).find("t.json: byte "), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dentmark::sim::scan
