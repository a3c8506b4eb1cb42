// saker-cli run as a newcomer runs it: through the shell, reading its output
// and exit code.

#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace {

struct CliRun {
  int exit_code = -1;
  std::string out;  // stdout and stderr together
};

CliRun RunCli(const std::string& arguments) {
  const std::string command = std::string(SAKER_CLI_PATH) + " " + arguments + " 2>&1";
  CliRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) run.out.append(buffer.data(), n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

TEST(CliTest, HelpListsTheCommands) {
  const CliRun run = RunCli("--help");
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_NE(run.out.find("probe"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("klv"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("Exit codes"), std::string::npos) << run.out;
}

TEST(CliTest, BadCommandLineExitsTwo) {
  EXPECT_EQ(RunCli("").exit_code, 2);
  EXPECT_EQ(RunCli("probe").exit_code, 2);
  EXPECT_EQ(RunCli("frobnicate x.ts").exit_code, 2);
  EXPECT_EQ(RunCli("probe x.ts --async-tolerance -3").exit_code, 2);
}

TEST(CliTest, MissingFileExitsOneAndNamesIt) {
  const CliRun run = RunCli("probe /nonexistent/sortie-7.ts");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("/nonexistent/sortie-7.ts"), std::string::npos) << run.out;
}

TEST(CliTest, ProbeSummarisesTheRealClip) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  const CliRun run = RunCli("probe '" + path.string() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("h264 720x480, 29.970 fps, 48 frames"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("48 packets, 48 EG 0104"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("48 of 48 with metadata, 48 with image corners"), std::string::npos)
      << run.out;
  // FFmpeg's own log lines stay off unless --verbose.
  EXPECT_EQ(run.out.find("[mpegts @"), std::string::npos) << run.out;
}

TEST(CliTest, JsonOutputsParse) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h265_tricky_klv.ts");
  const CliRun probe = RunCli("probe --json '" + path.string() + "'");
  ASSERT_EQ(probe.exit_code, 0) << probe.out;
  const auto summary = nlohmann::json::parse(probe.out);
  EXPECT_EQ(summary["klv_streams"].size(), 3u);
  EXPECT_EQ(summary["klv_streams"][0]["timing"], "synchronous");
  EXPECT_EQ(summary["metadata"]["packets"], 90);

  const CliRun klv = RunCli("klv --json '" + path.string() + "'");
  ASSERT_EQ(klv.exit_code, 0);
  const auto dump = nlohmann::json::parse(klv.out);
  ASSERT_EQ(dump["packets"].size(), 90u);
  // Every tag is listed, nested sets raw: the security set (tag 48) of the
  // first packet of the exhaustive (synchronous) stream.
  const int exhaustive_stream = summary["klv_streams"][0]["stream"];
  bool found_security = false;
  for (const auto& packet : dump["packets"]) {
    if (packet["stream"] != exhaustive_stream) continue;
    for (const auto& item : packet["items"]) {
      if (item["tag"] == 48) found_security = !item["raw"].get<std::string>().empty();
    }
    break;
  }
  EXPECT_TRUE(found_security);
}

}  // namespace
