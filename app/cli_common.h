#pragma once

// What every saker-cli subcommand shares: exit codes, how a failure is reported, the progress
// line, and options that several subcommands take.

#include "core/frontend/front_end.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <CLI/CLI.hpp>

#include <string>

namespace saker::app {

// Exit codes (documented in the README, "Exit codes").
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;       // the input could not be read or the job failed
inline constexpr int kExitUsage = 2;        // bad command line
inline constexpr int kExitBug = 3;          // an internal check failed
inline constexpr int kExitCancelled = 130;  // as a shell reports a job stopped by Ctrl-C

// Prints "saker-cli: <message>" on stderr (after the progress line, when one is shown) and
// returns the exit code for `status`: kExitCancelled for a cancellation, else kExitFailed.
int Fail(const Status& status, bool progress_shown = false);

// Progress on one stderr line, rewritten in place; silent when quiet or when stderr is not a
// terminal (a log file would collect every update).
JobContext ProgressContext(bool quiet);

// Clears the progress line when one was shown (`shown`) on a terminal.
void ClearProgressLine(bool shown);

// `--adjust full|decomposed` (mosaic::ParseAdjustmentMode reads it), shared by the subcommands
// that build a mosaic.
CLI::Option* AddAdjustOption(CLI::App* command, std::string* mode);

// `--accept-bad-checksums` (ingest::AlignmentOptions::accept_bad_checksums), shared by the
// subcommands that tie KLV metadata to frames.
CLI::Option* AddAcceptBadChecksumsFlag(CLI::App* command, bool* accept);

// `--overlay-mask on|off` (track::OverlayOptions::enabled; a bare `--overlay-mask` is on), shared
// by the subcommands that run the front end. `*enabled` holds the default.
CLI::Option* AddOverlayMaskOption(CLI::App* command, bool* enabled);
// `--horizon-mask on|off` (track::HorizonOptions::enabled), the same way.
CLI::Option* AddHorizonMaskOption(CLI::App* command, bool* enabled);
// `--noise-thresholds measured|fixed`: `*fixed` is set for `fixed`
// (frontend::FrontEndOptions::UseFixedThresholds), shared the same way.
CLI::Option* AddNoiseThresholdsOption(CLI::App* command, bool* fixed);

// `--min-confidence X`: a number from 0 to 1 (activity/confidence.h); anything else is refused
// with a message naming the value. `what` says what happens to the tracks below it.
CLI::Option* AddMinConfidenceOption(CLI::App* command, double* min_confidence,
                                    const std::string& what);

// `--low-frame-rate auto|on|off` (frontend::LowFrameRateOptions::mode), shared by the subcommands
// that run the front end.
CLI::Option* AddLowFrameRateOption(CLI::App* command, frontend::LowFrameRateOptions::Mode* mode);

}  // namespace saker::app
