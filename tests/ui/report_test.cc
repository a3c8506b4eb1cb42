// The mission report on the small simulated mission: HTML that stands alone (every picture
// inlined), the facts, the track table and a chip per track, the analyst's verdicts and notes
// (escaped), the bookmarks, tracks marked false left out; PDF through Qt's writer; no video means
// no chips and a warning, not a failure.

#include "core/report/report.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/export_mission.h"
#include "tests/testing/test_data.h"
#include "tests/ui/ui_testing.h"
#include "ui/report_pdf.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace saker::ui {
namespace {

namespace fs = std::filesystem;
using testing::SmallMission;
using testing::TestMission;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(ReportTest, HtmlStandsAloneWithChipsVerdictsAndBookmarks) {
  const TestMission* m = SmallMission();
  ASSERT_NE(m, nullptr);
  mission::Mission mission = m->loaded;
  ASSERT_GE(mission.tracks.size(), 3u);
  const int64_t hidden = mission.tracks[0].id, judged = mission.tracks[1].id;
  mission.reviews = {{hidden, mission::Verdict::kFalse, mission::TargetLabel::kNone, ""},
                     {judged, mission::Verdict::kConfirmed, mission::TargetLabel::kPerson,
                      "<script>alert(1)</script> & co"}};
  std::sort(mission.reviews.begin(), mission.reviews.end(),
            [](const auto& a, const auto& b) { return a.track_id < b.track_id; });
  mission.bookmarks = {{1, 3.5, mission.tracks[1].points.front().map, "meeting point"}};
  auto store = mission::MissionStore::Open(m->mission.string());
  ASSERT_TRUE(store.ok());
  report::ReportOptions options;
  options.video_path = m->video.string();
  options.saker_version = "test";
  const auto built = report::BuildReport(
      mission, pipeline::StoreTileReader(**store, mission.pyramid ? mission.pyramid->tile_size : 0),
      options);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  EXPECT_TRUE(built->warnings.empty()) << built->warnings.front();
  const size_t reported = mission.tracks.size() - 1;  // less the false one
  EXPECT_EQ(built->tracks, static_cast<int>(reported));
  // The activity map and a chip per reported track.
  EXPECT_EQ(built->images.size(), 1 + reported);
  const std::string html = built->Html();
  EXPECT_EQ(Count(html, "src=\"data:image/jpeg;base64,"), 1 + reported);
  for (const report::ReportImage& image : built->images) {
    EXPECT_EQ(html.find("src=\"" + image.name + "\""), std::string::npos) << "inlined";
    EXPECT_EQ(image.bytes[0], 0xFF);  // JPEG
  }
  EXPECT_EQ(html.find("<script>"), std::string::npos) << "notes are escaped";
  EXPECT_NE(html.find("&lt;script&gt;alert(1)&lt;/script&gt; &amp; co"), std::string::npos);
  EXPECT_NE(html.find("meeting point"), std::string::npos);
  EXPECT_NE(html.find("<b>Track " + std::to_string(judged) + "</b>"), std::string::npos);
  EXPECT_EQ(html.find("<b>Track " + std::to_string(hidden) + "</b>"), std::string::npos);
  EXPECT_NE(html.find("confirmed"), std::string::npos);

  // Written as one file; as PDF through Qt.
  const fs::path dir = saker::testing::MakeTempDir("saker-report");
  ASSERT_TRUE(report::WriteHtml(*built, (dir / "report.html").string()).ok());
  EXPECT_EQ(ReadText(dir / "report.html"), html);
  ASSERT_TRUE(WriteReportPdf(*built, (dir / "report.pdf").string()).ok());
  const std::string pdf = ReadText(dir / "report.pdf");
  EXPECT_EQ(pdf.rfind("%PDF-", 0), 0u);
  EXPECT_GT(pdf.size(), 20000u) << "the pictures are in it";
  const Status unwritable = WriteReportPdf(*built, (dir / "no" / "such" / "r.pdf").string());
  EXPECT_FALSE(unwritable.ok());
  EXPECT_NE(unwritable.message().find("r.pdf"), std::string::npos) << unwritable.message();

  // Without the video: no chips, a warning in the report and beside it, still a report.
  options.video_path = (dir / "gone.ts").string();
  const auto without = report::BuildReport(
      mission, pipeline::StoreTileReader(**store, mission.pyramid ? mission.pyramid->tile_size : 0),
      options);
  ASSERT_TRUE(without.ok()) << without.status().ToString();
  EXPECT_EQ(without->images.size(), 1u);
  ASSERT_FALSE(without->warnings.empty());
  EXPECT_NE(without->warnings.front().find("gone.ts"), std::string::npos);
  EXPECT_NE(without->body.find("no chips"), std::string::npos);
}

TEST(ReportTest, Base64AndEscaping) {
  EXPECT_EQ(report::Base64({}), "");
  EXPECT_EQ(report::Base64({'M'}), "TQ==");
  EXPECT_EQ(report::Base64({'M', 'a'}), "TWE=");
  EXPECT_EQ(report::Base64({'M', 'a', 'n'}), "TWFu");
  EXPECT_EQ(report::Base64({0xFF, 0xEF, 0x00, 0x10}), "/+8AEA==");
  EXPECT_EQ(report::HtmlText("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&#39;");
  // Invalid UTF-8 becomes U+FFFD, control characters go, valid text stays.
  EXPECT_EQ(report::HtmlText("x\xFFy\x01z é"), "x\xEF\xBF\xBDyz é");
}

}  // namespace
}  // namespace saker::ui
