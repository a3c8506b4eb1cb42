#include "app/cli_common.h"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

namespace saker::app {

int Fail(const Status& status, bool progress_shown) {
  if (progress_shown && isatty(STDERR_FILENO) != 0) std::cerr << "\n";
  std::cerr << "saker-cli: " << status.message() << "\n";
  return status.code() == StatusCode::kCancelled ? kExitCancelled : kExitFailed;
}

JobContext ProgressContext(bool quiet) {
  if (quiet || isatty(STDERR_FILENO) == 0) return JobContext();
  return JobContext(
      [last = std::string(), percent = -1](const std::string& stage, double fraction) mutable {
        const int p = static_cast<int>(fraction * 100);
        if (stage == last && p == percent) return;
        last = stage;
        percent = p;
        std::cerr << "\r" << stage << ": " << p << " %   " << std::flush;
      });
}

void ClearProgressLine(bool shown) {
  if (shown && isatty(STDERR_FILENO) != 0) std::cerr << "\r" << std::string(60, ' ') << "\r";
}

CLI::Option* AddAdjustOption(CLI::App* command, std::string* mode) {
  return command
      ->add_option("--adjust", *mode,
                   "Bundle adjustment of every key frame (full) or of the nodes of the node/arc "
                   "decomposition, the other key frames then placed along the arcs (decomposed)")
      ->capture_default_str()
      ->check(CLI::IsMember({"full", "decomposed"}));
}

CLI::Option* AddAcceptBadChecksumsFlag(CLI::App* command, bool* accept) {
  return command->add_flag(
      "--accept-bad-checksums", *accept,
      "Use KLV packets that failed their checksum for frames' times, positions and footprints "
      "(by default they are counted and shown, never used: one flipped bit can move a frame by "
      "hours or kilometres)");
}

namespace {

// An on|off switch, a bare flag meaning on; `what` ends before the values and the default.
CLI::Option* AddOnOffOption(CLI::App* command, const std::string& name, bool* enabled,
                            const std::string& what, const std::string& docs) {
  return command
      ->add_option_function<std::string>(
          name, [enabled](const std::string& text) { *enabled = text != "off"; },
          what + ": on or off (a bare " + name + " is on; default: " + (*enabled ? "on" : "off") +
              "; " + docs + ")")
      ->check(CLI::IsMember({"on", "off"}))
      ->expected(0, 1)
      ->type_name("on|off");
}

}  // namespace

CLI::Option* AddOverlayMaskOption(CLI::App* command, bool* enabled) {
  return AddOnOffOption(command, "--overlay-mask", enabled,
                        "Find screen-fixed overlays (burned-in HUD text, reticles, logos) and keep "
                        "them out of the ground motion, change detection and targets, where they "
                        "would become false tracks",
                        "docs/front-end.md, Overlays");
}

CLI::Option* AddHorizonMaskOption(CLI::App* command, bool* enabled) {
  return AddOnOffOption(command, "--horizon-mask", enabled,
                        "Find the horizon of low oblique views and keep the sky and the distant "
                        "ground above it out of the ground motion, key frames, change detection "
                        "and targets, where clouds and haze would become false tracks",
                        "docs/front-end.md, Oblique views");
}

CLI::Option* AddNoiseThresholdsOption(CLI::App* command, bool* fixed) {
  return command
      ->add_option_function<std::string>(
          "--noise-thresholds", [fixed](const std::string& text) { *fixed = text == "fixed"; },
          "The motion thresholds: raised where the video's own measured noise (heavy "
          "compression, sensor noise) asks for it, so that the ground does not become tracks "
          "(measured, the default), or the fixed ones tuned on clean video alone (fixed; "
          "docs/front-end.md, Noisy video)")
      ->check(CLI::IsMember({"measured", "fixed"}))
      ->type_name("measured|fixed");
}

CLI::Option* AddMinConfidenceOption(CLI::App* command, double* min_confidence,
                                    const std::string& what) {
  const CLI::Validator zero_to_one(
      [](const std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value) ||
            value < 0 || value > 1) {
          return "\"" + text + "\" is not a confidence: give a number from 0 to 1";
        }
        return {};
      },
      "0..1");
  return command
      ->add_option("--min-confidence", *min_confidence,
                   "Tracks whose confidence (0 to 1: how long they were seen, how steadily they "
                   "moved, feature and change support, a plausible speed; docs/activity.md) is "
                   "below this " +
                       what + "; with a value above 0, tracks of unknown confidence too")
      ->capture_default_str()
      ->check(zero_to_one);
}

CLI::Option* AddLowFrameRateOption(CLI::App* command, frontend::LowFrameRateOptions::Mode* mode) {
  using Mode = frontend::LowFrameRateOptions::Mode;
  std::vector<std::string> names;
  for (const Mode m : {Mode::kAuto, Mode::kOn, Mode::kOff}) {
    names.push_back(frontend::LowFrameRateModeName(m));
  }
  return command
      ->add_option_function<std::string>(
          "--low-frame-rate",
          [mode](const std::string& text) { *mode = *frontend::ParseLowFrameRateMode(text); },
          "Targets from change detection alone (each frame against its registered frames at "
          "least 0.6 s before and after, the edges of a fast pan against the two on the side "
          "that sees them), tracked "
          "with a motion model and gates that follow a plausible top speed (feature tracks a "
          "second apart do not label motion): auto (below 8 frames a second), on or off "
          "(docs/front-end.md, Low frame rates)")
      ->check(CLI::IsMember(names))
      ->type_name("MODE")
      ->default_str(frontend::LowFrameRateModeName(*mode));
}

}  // namespace saker::app
