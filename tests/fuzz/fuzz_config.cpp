// libFuzzer target: the configuration reader (rt/config: toml++ and the schema readers) over
// arbitrary text, through the same entry points the path loaders use (load_*_text: the path
// loaders read the file and end there).
//   byte 0 % 3 = 0: a device file    load_device_text(text, config/devices/fuzz.toml)
//   byte 0 % 3 = 1: a scene file     load_scene_text(text, config/scenes/fuzz.toml, options)
//   byte 0 % 3 = 2: a model file     load_model_definition_text(text, config/models/fuzz.toml)
// The rest of the input is the file's text. The names are virtual files in the source tree's
// config/ directories, so relative references resolve as they do for the repository's files:
// a scene's device reference is replaced by the fixed good config/devices/sim.toml
// (LoadOptions::device_file, as `trainer --device` does: the device reader is fuzzed on its
// own), its [[model]] definitions are the real files it names (config/models/*.toml, read
// from disk; a mutated name that exists elsewhere is read too, read-only), its script need not
// exist (require_script_file = false).
//
// Invariants besides ASan/UBSan and no hang (-timeout): a refused input has a message that
// names a file (the virtual name, or for a scene a file it refers to), and is never the
// "internal error" of an ErrorSink asked for an error it did not record; an accepted one holds
// the counts and names its struct promises (docs/config.md). Counters of accepted and refused
// inputs per file type are printed at exit (at the end of a -runs run, or of a run over a corpus
// with -runs=0), so a run shows that inputs get past the TOML syntax to the schema readers.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

#include "fuzz_input.hpp"
#include "trainer/config/device.hpp"
#include "trainer/config/model.hpp"
#include "trainer/config/scene.hpp"

namespace {

using namespace trainer::config;  // NOLINT: a fuzz target, one file

const std::filesystem::path kConfigDir{TRAINER_FUZZ_CONFIG_DIR};

struct ConfigCounters {
  std::array<std::uint64_t, 3> accepted{};
  std::array<std::uint64_t, 3> syntax_errors{};  // refused by toml++
  std::array<std::uint64_t, 3> refused{};        // refused by the schema readers
  ~ConfigCounters() {
    const char* names[] = {"device", "scene", "model definition"};
    for (std::size_t i = 0; i < 3; ++i) {
      std::fprintf(stderr, "fuzz_config: %s files: %llu accepted, %llu syntax errors, %llu refused "
                   "by the reader\n", names[i], static_cast<unsigned long long>(accepted[i]),
                   static_cast<unsigned long long>(syntax_errors[i]),
                   static_cast<unsigned long long>(refused[i]));
    }
  }
};
ConfigCounters g_config_counters;

template <class T>
void count(std::size_t mode, const trainer::core::Expected<T>& result) {
  if (result) {
    ++g_config_counters.accepted[mode];
  } else if (result.error().message.find(": syntax error: ") != std::string::npos) {
    ++g_config_counters.syntax_errors[mode];
  } else {
    ++g_config_counters.refused[mode];
  }
}

void check_refusal(const trainer::core::Error& error, std::string_view file_name,
                   bool may_name_other_file) {
  const std::string& message = error.message;
  FUZZ_CHECK(!message.empty());
  // The ErrorSink's "internal error: ..." (an error requested but none recorded) is the whole
  // message, with no file; a value quoted in a real message may contain those words.
  FUZZ_CHECK(!message.starts_with("internal error"));
  const bool names_file = message.find(file_name) != std::string::npos;
  FUZZ_CHECK(names_file || (may_name_other_file && message.find('/') != std::string::npos));
}

void check_device(const DeviceConfig& device) {
  FUZZ_CHECK(!device.name.empty());
  FUZZ_CHECK(!device.instruments.empty() && device.instruments.size() <= kMaxDeviceInstruments);
  FUZZ_CHECK(device.backend == "sim" || device.backend == "canopen" || device.backend == "usb");
}

void check_scene(const SceneConfig& scene) {
  FUZZ_CHECK(!scene.name.empty());
  FUZZ_CHECK(!scene.instruments.empty() && scene.instruments.size() <= kMaxSceneInstruments);
  FUZZ_CHECK(scene.objects.size() <= kMaxObjects && scene.models.size() <= kMaxModels);
  FUZZ_CHECK(scene.loop.period_ns > 0);
  for (const ObjectConfig& object : scene.objects) {
    for (std::size_t index : object.touched_by) FUZZ_CHECK(index < scene.instruments.size());
  }
  for (const SceneModelConfig& model : scene.models) {
    FUZZ_CHECK(!model.name.empty());
    for (std::size_t index : model.touched_by) FUZZ_CHECK(index < scene.instruments.size());
  }
  check_device(scene.device);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  switch (data[0] % 3) {
    case 0: {
      const std::filesystem::path file = kConfigDir / "devices" / "fuzz.toml";
      auto device = load_device_text(text, file);
      count(0, device);
      if (device) {
        check_device(*device);
      } else {
        check_refusal(device.error(), "fuzz.toml", false);
      }
      break;
    }
    case 1: {
      const std::filesystem::path file = kConfigDir / "scenes" / "fuzz.toml";
      LoadOptions options;
      options.require_script_file = false;
      options.device_file = kConfigDir / "devices" / "sim.toml";
      auto scene = load_scene_text(text, file, options);
      count(1, scene);
      if (scene) {
        check_scene(*scene);
      } else {
        check_refusal(scene.error(), "fuzz.toml", true);
      }
      break;
    }
    default: {
      const std::filesystem::path file = kConfigDir / "models" / "fuzz.toml";
      auto model = load_model_definition_text(text, file);
      count(2, model);
      if (model) {
        FUZZ_CHECK(!model->name.empty());
      } else {
        check_refusal(model.error(), "fuzz.toml", false);
      }
      break;
    }
  }
  return 0;
}
