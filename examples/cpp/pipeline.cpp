// A C++ pipeline over rangewalk's C ABI: load the Cornell box, render a
// frame, bake small, synthesize from four threads at once, and check that
// the library's frames are the ones the command line writes for the same
// view (bit for bit).
//
//   pipeline <scene.toml> <work dir> <path of the rangewalk command>

#include <rangewalk.h>

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

// Throws with the library's message when a call fails.
void check(rw_status status, const char *what) {
  if (status == RW_OK) return;
  std::string message(rw_last_error(nullptr, 0) + 1, '\0');
  rw_last_error(message.data(), message.size());
  message.pop_back();
  throw std::runtime_error(std::string(what) + ": " + rw_status_name(status) + ": " + message);
}

// Owners of the library's handles: each is freed exactly once.
struct Scene {
  rw_scene *p = nullptr;
  explicit Scene(const std::string &path) { check(rw_scene_load(path.c_str(), &p), "rw_scene_load"); }
  ~Scene() { rw_scene_free(p); }
  Scene(const Scene &) = delete;
  Scene &operator=(const Scene &) = delete;
};

struct Bake {
  rw_bake *p = nullptr;
  explicit Bake(const std::string &dir) { check(rw_bake_open(dir.c_str(), &p), "rw_bake_open"); }
  ~Bake() { rw_bake_free(p); }
  Bake(const Bake &) = delete;
  Bake &operator=(const Bake &) = delete;
};

// The named channels of an EXR the command line wrote, pixel-interleaved.
std::vector<float> read_channels(const std::string &path, const std::vector<std::string> &names,
                                 int width, int height) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw std::runtime_error(path + ": " + OIIO::geterror());
  const OIIO::ImageSpec &spec = in->spec();
  if (spec.width != width || spec.height != height)
    throw std::runtime_error(path + ": " + std::to_string(spec.width) + "x" +
                             std::to_string(spec.height) + ", not the size asked");
  std::vector<float> all(size_t(width) * height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
    throw std::runtime_error(path + ": " + in->geterror());
  std::vector<int> index;
  for (const auto &n : names) {
    int c = spec.channelindex(n);
    if (c < 0) throw std::runtime_error(path + ": no channel " + n);
    index.push_back(c);
  }
  std::vector<float> out;
  out.reserve(size_t(width) * height * names.size());
  for (size_t p = 0; p < size_t(width) * height; ++p)
    for (int c : index) out.push_back(all[p * spec.nchannels + c]);
  return out;
}

// How many values differ, and the largest difference.
void require_identical(const std::vector<float> &a, const std::vector<float> &b, const char *what) {
  size_t differ = 0;
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i] != b[i]) {
      ++differ;
      worst = std::fmax(worst, std::fabs(double(a[i]) - b[i]));
    }
  if (a.size() != b.size() || differ)
    throw std::runtime_error(std::string(what) + ": " + std::to_string(differ) + " of " +
                             std::to_string(a.size()) + " values differ (largest by " +
                             std::to_string(worst) + ")");
  std::printf("%s: identical (%zu values)\n", what, a.size());
}

void run(const std::string &cli, const std::string &args) {
  std::string command = "\"" + cli + "\" " + args + " > /dev/null";
  if (std::system(command.c_str()) != 0) throw std::runtime_error("failed: " + command);
}

bool on_progress(void *userdata, float fraction) {
  auto *calls = static_cast<int *>(userdata);
  ++*calls;
  std::printf("  bake progress %3.0f%%\n", 100.0 * fraction);
  return true;
}

}  // namespace

int main(int argc, char **argv) try {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s <scene.toml> <work dir> <rangewalk command>\n", argv[0]);
    return 2;
  }
  const std::string scene_path = argv[1], work = argv[2], cli = argv[3];
  std::filesystem::remove_all(work);
  std::filesystem::create_directories(work);
  std::printf("rangewalk %s\n", rw_version());

  Scene scene(scene_path);
  rw_view view;
  check(rw_scene_camera(scene.p, "main", &view), "rw_scene_camera");

  // A path-traced frame, and the one `rangewalk render` writes.
  const uint32_t rw = 64, rh = 48, spp = 4;
  const uint64_t seed = 7;
  const float time = 0.5f;
  std::vector<float> rendered(size_t(rw) * rh * 3);
  check(rw_render(scene.p, &view, time, rw, rh, spp, seed, rendered.data()), "rw_render");
  run(cli, "render " + scene_path + " --camera main --time 0.5 --size 64x48 --spp 4 --seed 7 --out " +
               work + "/render-cli.exr");
  require_identical(rendered, read_channels(work + "/render-cli.exr", {"R", "G", "B"}, rw, rh),
                    "rw_render against `rangewalk render`");

  // A small bake.
  rw_bake_options options;
  check(rw_bake_options_default(&options), "rw_bake_options_default");
  options.quality = 0.3f;
  options.size = 64;
  options.spp = 2;
  const std::string bake_dir = work + "/bake";
  int progress_calls = 0;
  check(rw_bake_run(scene.p, &options, bake_dir.c_str(), on_progress, &progress_calls), "rw_bake_run");
  if (progress_calls < 2) throw std::runtime_error("the bake reported its progress fewer than twice");

  // Four threads synthesize at once, each the main view at t = 0.5 and a
  // frame of the walk path at its own time, twice over.
  Bake bake(bake_dir);
  size_t views = 0;
  check(rw_bake_view_count(bake.p, &views), "rw_bake_view_count");
  for (size_t v = 0; v < views; ++v) {
    float position[3];
    size_t times = 0;
    check(rw_bake_view(bake.p, v, position, nullptr, 0, &times), "rw_bake_view");
    std::printf("base view %zu at (%g, %g, %g): %zu times\n", v, position[0], position[1], position[2], times);
  }
  const uint32_t w = 96, h = 72;
  const size_t n = size_t(w) * h;
  std::vector<std::vector<float>> rgb(4, std::vector<float>(n * 3)), dist(4, std::vector<float>(n));
  std::vector<std::string> failures(4);
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i)
    threads.emplace_back([&, i] {
      try {
        rw_view walk;
        check(rw_scene_path_view(scene.p, "walk", 0.25f * i, &walk), "rw_scene_path_view");
        std::vector<float> other(n * 3);
        for (int round = 0; round < 2; ++round) {
          check(rw_synth(bake.p, &view, time, w, h, rgb[i].data(), dist[i].data()), "rw_synth");
          check(rw_synth(bake.p, &walk, 0.25f * i, w, h, other.data(), nullptr), "rw_synth (walk)");
        }
      } catch (const std::exception &e) {
        failures[i] = e.what();
      }
    });
  for (auto &t : threads) t.join();
  for (int i = 0; i < 4; ++i)
    if (!failures[i].empty()) throw std::runtime_error("thread " + std::to_string(i) + ": " + failures[i]);
  for (int i = 1; i < 4; ++i) require_identical(rgb[0], rgb[i], "thread 0 against another thread");

  // The frame `rangewalk synth` writes for the same view.
  run(cli, "synth " + bake_dir + " --camera main --time 0.5 --size 96x72 --out " + work + "/synth-cli.exr");
  const std::string cli_frame = work + "/synth-cli.exr";
  require_identical(rgb[0], read_channels(cli_frame, {"R", "G", "B"}, w, h),
                    "rw_synth radiance against `rangewalk synth`");
  require_identical(dist[0], read_channels(cli_frame, {"distance"}, w, h),
                    "rw_synth distance against `rangewalk synth`");

  // Options reach the library: the splat filter that takes only covered
  // pixels, against `rangewalk synth --filter cover`.
  rw_synth_options options_cover;
  check(rw_synth_options_default(&options_cover), "rw_synth_options_default");
  options_cover.filter = RW_FILTER_COVER;
  std::vector<float> covered(n * 3);
  check(rw_synth_with(bake.p, &view, time, w, h, &options_cover, covered.data(), nullptr), "rw_synth_with");
  run(cli, "synth " + bake_dir + " --camera main --time 0.5 --size 96x72 --filter cover --out " + work +
               "/synth-cover.exr");
  require_identical(covered, read_channels(work + "/synth-cover.exr", {"R", "G", "B"}, w, h),
                    "rw_synth_with RW_FILTER_COVER against `rangewalk synth --filter cover`");
  if (covered == rgb[0]) throw std::runtime_error("RW_FILTER_COVER gave the default filter's frame");
  std::printf("pipeline: all checks passed\n");
  return 0;
} catch (const std::exception &e) {
  std::fprintf(stderr, "pipeline: %s\n", e.what());
  return 1;
}
