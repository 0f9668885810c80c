// detect, eval and synth scan: thin wrappers over ingest, detect, report and sim/scan.
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.h"
#include "dentmark/common/huge_pages.h"
#include "dentmark/common/ingest/mesh_writer.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/dml_file.h"
#include "dentmark/host/detect/detector.h"
#include "dentmark/host/ingest/read_mesh.h"
#include "dentmark/host/ingest/units.h"
#include "dentmark/host/report/defects_json.h"
#include "dentmark/host/report/evaluate.h"
#include "dentmark/host/report/pictures.h"
#include "dentmark/host/report/scan_truth.h"
#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::cli {
namespace {

struct DetectArgs {
  std::string scan, units = "auto", config, out, json, report, ply;
  bool verbose = false;
  std::string panel;                 // the panel model the edge tracks (its taught template's name)
  std::optional<std::uint64_t> job;  // default: the scan time in milliseconds
  std::optional<double> scan_time;   // s since the epoch; default: the scan file's modification time
};

// When the scan was taken: the scanner writes its file right after the exposure, so
// the file's modification time stands for it unless the caller knows better.
double scan_file_time(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return 0.0;
  return static_cast<double>(st.st_mtim.tv_sec) + 1e-9 * static_cast<double>(st.st_mtim.tv_nsec);
}

// A time (s since the epoch) as the report prints it: "2026-12-06 02:30 UTC".
std::string utc_minutes(double t) {
  const auto secs = static_cast<std::time_t>(t);
  std::tm tm{};
  if (::gmtime_r(&secs, &tm) == nullptr) return "";
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &tm);
  return text;
}

struct EvalArgs {
  std::vector<std::string> truth, defects;
};

struct SynthArgs {
  std::string out, truth;
  sim::scan::ScanOptions options;
  bool paper = false, paper_bump = false;
  bool no_crease = false, no_handle = false, no_window = false;
  std::vector<std::string> lines;       // --character-line Y,ANGLE,STEP,WIDTH
  std::vector<std::string> near_lines;  // --near-lines: gaps in m, or "on"
  std::vector<double> tilt;             // --tilt YAW,PITCH,ROLL (rad)
};

// "Y,ANGLE,STEP,WIDTH": a character line through (width/2, Y x height) at ANGLE rad,
// a step of STEP m over WIDTH m. Throws std::invalid_argument naming the field.
sim::scan::CharacterLine parse_character_line(const std::string& text, const sim::scan::PanelShape& shape) {
  double f[4];
  std::size_t pos = 0;
  static const char* names[4] = {"Y", "ANGLE", "STEP", "WIDTH"};
  for (int k = 0; k < 4; ++k) {
    const std::size_t end = k < 3 ? text.find(',', pos) : text.size();
    if (end == std::string::npos)
      throw std::invalid_argument("--character-line '" + text + "': expected Y,ANGLE,STEP,WIDTH");
    const std::string field = text.substr(pos, end - pos);
    char* stop = nullptr;
    f[k] = std::strtod(field.c_str(), &stop);
    if (field.empty() || *stop != '\0' || !std::isfinite(f[k]))
      throw std::invalid_argument("--character-line '" + text + "': field " + names[k] + " '" + field +
                                  "' is not a number");
    pos = end + 1;
  }
  sim::scan::CharacterLine l;
  l.point = {0.5 * shape.width, f[0] * shape.height};
  l.angle = f[1], l.step = f[2], l.width = f[3];
  return l;
}

// The synth options from the command line's extras; throws std::invalid_argument.
void apply_placements(SynthArgs& a) {
  a.options.shape.crease = !a.no_crease;
  a.options.shape.handle = !a.no_handle;
  a.options.shape.window = !a.no_window;
  for (const std::string& l : a.lines)
    a.options.shape.lines.push_back(parse_character_line(l, a.options.shape));
  for (const std::string& g : a.near_lines) {
    if (g == "on") {
      a.options.near_lines.push_back(-1.0);
      continue;
    }
    char* stop = nullptr;
    const double v = std::strtod(g.c_str(), &stop);
    if (g.empty() || *stop != '\0' || !std::isfinite(v))
      throw std::invalid_argument("--near-lines: '" + g + "' is neither a gap in m nor 'on'");
    a.options.near_lines.push_back(v);
  }
  if (!a.tilt.empty()) {
    for (const double v : a.tilt)
      if (!(std::abs(v) <= 0.5 * std::numbers::pi))
        throw std::invalid_argument("--tilt: each of YAW,PITCH,ROLL must be a number within pi/2 rad");
    a.options.tilt = Eigen::Vector3d(a.tilt[0], a.tilt[1], a.tilt[2]);
  }
  if (a.paper_bump) {
    // The paper's bump (§V): 9 mm wide, 11 mm high, 30 % along the door, 27.5 % up.
    a.options.planted.push_back(
        {{0.30 * a.options.shape.width, 0.275 * a.options.shape.height}, 0.009, 0.011});
  }
}

// The .dml for the edge box: the defects, stamped with the job, the panel model and
// when the scan was taken.
void write_defect_list(const DetectArgs& a, const detect::Detection& det) {
  protocol::DefectList list = report::to_defect_list(det);
  list.scan_time = a.scan_time.value_or(scan_file_time(a.scan));
  list.job_id = a.job.value_or(static_cast<std::uint64_t>(std::llround(list.scan_time * 1e3)));
  list.panel_id = a.panel;
  protocol::write_dml(a.out, list);
}

// Opens the scan in the units asked for; with --units auto, a scan that looks like
// millimetres is read again as such. 'spacing': the point spacing measured on the way
// (detection needs it too), kept only when the scan was read as metres. Throws IngestError.
ingest::Scan open_scan_in_units(const DetectArgs& a, bool tty, std::optional<double>& spacing) {
  ingest::ReadOptions ro;
  ro.scale_to_m = a.units == "mm" ? 1e-3 : 1.0;
  if (tty) ro.progress = [](double f) { std::fprintf(stderr, "\rreading %3.0f %%", 100 * f); };
  ingest::Scan scan = ingest::open_scan(a.scan, ro);
  if (a.units != "auto") return scan;
  const ingest::ScaleEvidence e = ingest::measure_scale(scan.mesh);
  spacing = e.spacing;
  if (!ingest::looks_like_millimetres(e)) return scan;
  spacing.reset();
  char note[256];
  std::snprintf(
      note, sizeof note,
      "%s: read as millimetres: it spans %.4g units, its samples %.3g apart (--units m to override)",
      a.scan.c_str(), e.extent, e.spacing);
  if (tty) std::fprintf(stderr, "\n");
  log::info(note);
  ro.scale_to_m = 1e-3;
  return ingest::open_scan(a.scan, ro);
}

// What detection did to the scan besides finding defects, one line each.
void log_scan_notes(const std::string& file, const ingest::Scan& scan, const detect::DetectionStats& st) {
  if (scan.cloud_charts > 0)
    log::info(file + ": the point cloud folds over in the sensor's view (merged views?): meshed in " +
              std::to_string(scan.cloud_charts) + " charts");
  if (st.rewound_triangles > 0)
    log::info(file + ": " + std::to_string(st.rewound_triangles) +
              " triangles were wound against their neighbours (a merged or re-exported mesh?): rewound");
  if (st.stray_triangles > 0)
    log::info(file + ": " + std::to_string(st.stray_triangles) +
              " triangles reach stray points far off the panel: left out");
  if (st.background_area > 0.0)
    log::info(file + ": " + std::to_string(static_cast<int>(std::lround(st.background_area * 1e4))) +
              " cm² of background (a surface far behind the panel) left out");
  if (st.charts > 1)
    log::info(file + ": the surface wraps round (over 45° from its mean normal): inspected in " +
              std::to_string(st.charts) + " charts (the report shows each)");
}

// The files asked for: defect list, JSON, report PNG, marked PLY. Throws on failure.
void write_outputs(const DetectArgs& a, const ingest::Scan& scan, const detect::Detection& det) {
  if (!a.out.empty()) write_defect_list(a, det);
  report::SourceInfo src{a.scan, scan.input_points, scan.mesh.triangle_count()};
  if (!a.json.empty()) {
    auto j = report::defects_to_json(det, src);
    j["timing"]["write"] = 0.0;
    report::write_text_file(a.json, j.dump(2) + "\n");
  }
  if (!a.report.empty())
    report::write_report_png(a.report, det,
                             {a.scan, utc_minutes(a.scan_time.value_or(scan_file_time(a.scan)))});
  if (!a.ply.empty()) report::write_marked_ply(a.ply, scan.mesh, det);
}

// --verbose: the scan's figures, memory and the time of each stage.
void print_details(const detect::Detection& det, double write_s, double total_s) {
  const auto& s = det.stats;
  std::printf(
      "scan: spacing %.3f mm, finest node %.3f mm (depth %d), %zu leaves, normal noise floor %.3f "
      "(spread %.3f, leaf threshold %.3f), %zu feature leaves in %zu groups, deviation noise %.1f um, "
      "working memory %.1f B/triangle\n",
      1e3 * s.spacing, 1e3 * s.leaf_size, s.depth, s.leaves, s.noise_floor_sigma, s.noise_floor_spread,
      s.leaf_sigma_threshold, s.feature_leaves, s.feature_groups, 1e6 * s.deviation_noise,
      static_cast<double>(s.working_bytes) / std::max<std::size_t>(1, s.triangles));
  struct rusage usage {};
  ::getrusage(RUSAGE_SELF, &usage);
  std::printf("memory: %s (%.0f MB in use), peak resident %.0f MB (the mapped scan included)\n",
              huge_pages_requested() ? "huge pages requested" : "small pages",
              static_cast<double>(huge_page_bytes_in_use()) / (1 << 20),
              static_cast<double>(usage.ru_maxrss) / 1024.0);
  for (const auto& [stage, sec] : det.timing) std::printf("timing %-10s %8.3f s\n", stage.c_str(), sec);
  std::printf("timing %-10s %8.3f s\ntiming %-10s %8.3f s\n", "write", write_s, "total", total_s);
}

int run_detect(const DetectArgs& a) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto seconds_since = [](Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
  };
  const bool tty = ::isatty(2) != 0;
  detect::DetectConfig config;
  try {
    if (!a.config.empty()) config = detect::load_config(a.config);
  } catch (const std::exception& e) {
    log::error(e.what());
    return 2;
  }
  std::optional<double> spacing;
  ingest::Scan scan;
  try {
    scan = open_scan_in_units(a, tty, spacing);
  } catch (const ingest::IngestError& e) {
    if (tty) std::fprintf(stderr, "\n");
    log::error(e.what());
    return 2;
  }
  const double read_s = seconds_since(start);
  const ingest::MeshView& mesh = scan.mesh;
  if (tty) std::fprintf(stderr, "\rdetecting on %zu triangles...", mesh.triangle_count());
  detect::Detection det;
  try {
    det = spacing ? detect::detect(mesh, config, *spacing) : detect::detect(mesh, config);
  } catch (const std::invalid_argument& e) {
    if (tty) std::fprintf(stderr, "\n");
    log::error(a.scan + ": " + e.what());
    return 2;
  }
  if (tty) std::fprintf(stderr, "\r%*s\r", 60, "");
  log_scan_notes(a.scan, scan, det.stats);
  det.timing.insert(det.timing.begin(), {"read", read_s});
  const auto t_detect = Clock::now();
  try {
    write_outputs(a, scan, det);
  } catch (const std::exception& e) {
    log::error(e.what());
    return 1;
  }
  const double write_s = seconds_since(t_detect);
  std::printf("%s: %zu triangles, %zu defects (%zu other features)\n", a.scan.c_str(), mesh.triangle_count(),
              det.defects.size(), det.features.size());
  for (const auto& f : det.defects) {
    const auto& d = f.defect;
    std::printf("  #%u %s at (%.4f, %.4f, %.4f) m, diameter %.1f mm, height %+.3f mm, score %.2f\n", d.id,
                report::class_name(d.defect_class), d.position.x(), d.position.y(), d.position.z(),
                1e3 * d.diameter, 1e3 * d.height, d.score);
  }
  if (a.verbose) print_details(det, write_s, seconds_since(start));
  return 0;
}

int run_eval(const EvalArgs& a) {
  if (a.truth.size() != a.defects.size()) {
    log::error("eval: give as many --truth as --defects files");
    return 2;
  }
  report::Evaluation total;
  try {
    for (std::size_t i = 0; i < a.truth.size(); ++i)
      total.add(report::evaluate(report::truth_for_evaluation(sim::scan::read_truth_file(a.truth[i])),
                                 report::read_defects_json(a.defects[i])));
  } catch (const report::ReportError& e) {
    log::error(e.what());
    return 2;
  } catch (const sim::scan::TruthFileError& e) {
    log::error(e.what());
    return 2;
  }
  std::printf("%s", report::format_evaluation(total).c_str());
  return 0;
}

int run_synth(SynthArgs a) {
  try {
    apply_placements(a);
  } catch (const std::invalid_argument& e) {
    log::error(std::string("synth scan: ") + e.what());
    return 2;
  }
  if (a.paper) {
    // The paper's test (§V): ~32 000 points, a 9 mm wide bump 11 mm high, the handle.
    a.options.spacing = 0.0045;
    a.options.noise = 1e-4;
    a.options.defects = 0;
    a.options.planted.push_back({{0.30, 0.22}, 0.009, 0.011});
  }
  sim::scan::SynthScan scan;
  try {
    scan = sim::scan::synthesize_scan(a.options);
  } catch (const std::invalid_argument& e) {
    log::error(std::string("synth scan: ") + e.what());
    return 2;
  }
  ingest::Mesh mesh;
  mesh.vertices = std::move(scan.vertices);
  mesh.triangles = std::move(scan.triangles);
  const nlohmann::json generator = {
      {"seed", a.options.seed},         {"spacing", a.options.spacing},
      {"noise", a.options.noise},       {"outlier_fraction", a.options.outlier_fraction},
      {"dropouts", a.options.dropouts}, {"holes", a.options.holes},
      {"shuffled", a.options.shuffle}};
  // The door's pose and size go with it: the station twin places the same door in the
  // tracking cameras' view.
  const sim::scan::TruthFile truth =
      sim::scan::truth_of(scan, a.options.shape.width, a.options.shape.height, generator);
  try {
    ingest::write_ply(a.out, mesh);
    if (!a.truth.empty()) report::write_text_file(a.truth, sim::scan::truth_to_json(truth).dump(1) + "\n");
  } catch (const std::exception& e) {
    log::error(e.what());
    return 1;
  }
  std::printf("%s: %zu vertices, %zu triangles, %zu planted defects, %.3f m²\n", a.out.c_str(),
              mesh.vertices.size(), mesh.triangles.size(), truth.defects.size(), truth.panel_area);
  return 0;
}

}  // namespace

void register_scan(CLI::App& app, CLI::App& synth) {
  auto d = std::make_shared<DetectArgs>();
  CLI::App* det = app.add_subcommand("detect", "Find dents and bumps on a scan (PLY, OBJ, STL, XYZ, PCD)");
  det->add_option("scan", d->scan, "Scan file")->required();
  det->add_option("--units", d->units,
                  "Units of the scan file; auto: metres unless the scan is over 20 units across or "
                  "sampled over 0.05 units apart, then millimetres")
      ->check(CLI::IsMember({"auto", "m", "mm"}))
      ->default_str("auto");
  det->add_option("--config", d->config, "YAML detection settings");
  det->add_option("--out", d->out, "Defect list, binary protocol file (.dml)")->required();
  det->add_option("--json", d->json, "Defect list as JSON (dentmark.defects/1)");
  det->add_option(
      "--report", d->report,
      "PNG report: deviation map with scale bar, defects numbered, design feature outlines, legend, "
      "defect table, title line");
  det->add_option("--ply", d->ply, "PLY: the mesh with defect triangles coloured");
  det->add_option("--panel", d->panel, "Panel model the edge box tracks this panel by (its taught template)");
  det->add_option("--job", d->job, "Job id of the defect list (default: the scan time in ms)");
  det->add_option("--scan-time", d->scan_time,
                  "When the scan was taken, s since the epoch (default: the scan file's modification time)")
      ->check(CLI::Range(0.0, 1e11));
  det->add_flag("--verbose,-v", d->verbose, "Per-stage timing and scan figures");
  det->callback([d] { exit_code() = run_detect(*d); });

  auto e = std::make_shared<EvalArgs>();
  CLI::App* ev = app.add_subcommand("eval", "Score defect lists against ground truth (pairs are pooled)");
  ev->add_option("--truth", e->truth, "Truth JSON from 'synth scan'")->required();
  ev->add_option("--defects", e->defects, "Defects JSON from 'detect --json'")->required();
  ev->callback([e] { exit_code() = run_eval(*e); });

  auto s = std::make_shared<SynthArgs>();
  CLI::App* sc = synth.add_subcommand("scan", "A door panel scanned by an SLS, with planted dents and bumps");
  sc->add_option("--out", s->out, "Output PLY (metres, sensor frame)")->required();
  sc->add_option("--truth", s->truth, "Ground truth JSON");
  sc->add_option("--seed", s->options.seed, "Random seed");
  sc->add_option("--spacing", s->options.spacing, "Sample spacing on the panel (m)");
  sc->add_option("--noise", s->options.noise, "Range noise, 1 sigma (m)");
  sc->add_option("--defects", s->options.defects, "Number of random dents and bumps");
  sc->add_option("--min-diameter", s->options.min_diameter, "m");
  sc->add_option("--max-diameter", s->options.max_diameter, "m");
  sc->add_option("--min-depth", s->options.min_depth, "m");
  sc->add_option("--max-depth", s->options.max_depth, "m");
  sc->add_option("--rim", s->options.rim,
                 "Each dent's ring of pushed-up metal (a bump's trough), as a fraction of its depth");
  sc->add_option("--outliers", s->options.outlier_fraction, "Fraction of points thrown 2-20 mm off");
  sc->add_option("--dropouts", s->options.dropouts, "Number of missing discs");
  sc->add_option("--holes", s->options.holes, "Number of through-holes (defects) showing the inner panel");
  sc->add_option("--width", s->options.shape.width, "Panel width (m)");
  sc->add_option("--height", s->options.shape.height, "Panel height (m)");
  sc->add_flag("--shuffle", s->options.shuffle, "Vertices and triangles in random order");
  sc->add_option("--tilt", s->tilt,
                 "YAW,PITCH,ROLL: the sensor's pose (rad; default: yaw and pitch drawn within 12 degrees)")
      ->delimiter(',')
      ->expected(3);
  sc->add_flag("--paper", s->paper, "The paper's case: ~32 k points, a 9 mm x 11 mm bump and the handle");
  sc->add_flag("--paper-bump", s->paper_bump, "Add the paper's 9 mm x 11 mm bump (at any spacing and noise)");
  sc->add_flag("--no-crease", s->no_crease, "No sharp crease");
  sc->add_flag("--no-handle", s->no_handle, "No handle");
  sc->add_flag("--no-window", s->no_window, "No window opening");
  sc->add_option("--character-line", s->lines,
                 "Y,ANGLE,STEP,WIDTH: a smooth step of STEP m over WIDTH m through (width/2, Y x height) at "
                 "ANGLE rad to x (repeat for several)");
  sc->add_option("--near-lines", s->near_lines,
                 "Gaps (m) from each character line's footprint to a defect's rim, one defect per gap and "
                 "line; 'on' centres one on the line")
      ->delimiter(',');
  sc->add_option(
        "--near-features", s->options.near_features,
        "Gaps (m) from the handle's, crease's, border's and window's footprints to a defect's rim, one "
        "defect per gap and feature")
      ->delimiter(',');
  sc->callback([s] { exit_code() = run_synth(*s); });
}

}  // namespace dentmark::cli
