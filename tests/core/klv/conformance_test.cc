// Conformance against KWIVER's decodes of its sample files: every ST 0601
// packet of kwiver/h264_klv.ts and kwiver/h265_tricky_klv.ts is extracted
// with the test TS reader, decoded, and compared tag by tag with the gold
// JSON (kwiver/video_stream_klv.json, kwiver/video_stream_tricky_klv.json).

#include "core/klv/decode.h"
#include "tests/core/klv/ts_extract.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>

namespace saker::klv {
namespace {

using nlohmann::json;

struct Tally {
  int packets = 0;
  int compared_values = 0;
  int raw_only = 0;  // gold has a structured value and we keep raw bytes
};

// The decoded packets of every data stream, by FFmpeg stream index.
std::map<int, std::vector<DecodedPacket>> DecodeFile(const std::filesystem::path& path) {
  const auto bytes = saker::testing::ReadFileBytes(path);
  std::string error;
  const auto streams = testing::ExtractTsStreams(bytes, &error);
  EXPECT_TRUE(error.empty()) << error;
  std::map<int, std::vector<DecodedPacket>> decoded;
  for (size_t index = 0; index < streams.size(); ++index) {
    for (const auto& unit : streams[index].units) {
      const KlvSplitResult split = SplitKlvPackets(unit);
      EXPECT_TRUE(split.errors.empty()) << split.errors.front();
      for (const auto& packet : split.packets) {
        decoded[static_cast<int>(index)].push_back(DecodePacket(packet));
      }
    }
  }
  return decoded;
}

// Compares one item with its gold value; returns true when a value was
// compared, false when the gold value is a structure we keep raw.
bool CompareItem(const St0601Item& item, const json& gold) {
  SCOPED_TRACE("tag " + std::to_string(item.tag) + " (" + St0601TagName(item.tag) + "), gold " +
               gold.dump());
  const St0601Value& v = item.value;
  const bool numeric = std::holds_alternative<double>(v) || std::holds_alternative<int64_t>(v) ||
                       std::holds_alternative<uint64_t>(v);
  auto as_double = [&v]() {
    if (auto* d = std::get_if<double>(&v)) return *d;
    if (auto* i = std::get_if<int64_t>(&v)) return static_cast<double>(*i);
    return static_cast<double>(std::get<uint64_t>(v));
  };
  if (gold.is_object() && gold.contains("length") && gold.contains("value") &&
      gold.at("value").is_number()) {
    EXPECT_EQ(gold.at("length").get<size_t>(), item.raw.size());
    EXPECT_TRUE(numeric) << "gold has a number, we have none";
    if (!numeric) return false;
    if (!std::holds_alternative<double>(v)) {
      EXPECT_EQ(as_double(), gold.at("value").get<double>()) << "integers are exact";
      return true;
    }
    const auto lsb = St0601Resolution(item.tag, item.raw.size());
    EXPECT_TRUE(lsb.has_value());
    EXPECT_NEAR(as_double(), gold.at("value").get<double>(), lsb.value_or(0));
    return true;
  }
  if (gold.is_string()) {
    EXPECT_TRUE(std::holds_alternative<std::string>(v));
    if (auto* s = std::get_if<std::string>(&v)) {
      EXPECT_EQ(*s, gold.get<std::string>());
    }
    return true;
  }
  if (gold.is_number_integer()) {
    EXPECT_TRUE(std::holds_alternative<uint64_t>(v) || std::holds_alternative<int64_t>(v));
    if (auto* u = std::get_if<uint64_t>(&v)) {
      EXPECT_EQ(*u, gold.get<uint64_t>());
    }
    if (auto* i = std::get_if<int64_t>(&v)) {
      EXPECT_EQ(*i, gold.get<int64_t>());
    }
    return true;
  }
  // Enumerations: {"integer": n, "string": name}.
  if (gold.is_object() && gold.size() == 2 && gold.contains("integer") && gold.contains("string")) {
    EXPECT_TRUE(std::holds_alternative<uint64_t>(v));
    if (auto* u = std::get_if<uint64_t>(&v)) {
      EXPECT_EQ(*u, gold.at("integer").get<uint64_t>());
    }
    return true;
  }
  // Bit flags: [{"integer": bit, "string": name}, ...] against our integer.
  if (gold.is_array() && std::holds_alternative<uint64_t>(v)) {
    uint64_t mask = 0;
    for (const auto& flag : gold) mask |= uint64_t{1} << flag.at("integer").get<int>();
    EXPECT_EQ(std::get<uint64_t>(v), mask);
    return true;
  }
  if (gold.is_null()) {
    EXPECT_TRUE(std::holds_alternative<std::monostate>(v) || std::holds_alternative<Absent>(v));
    return false;
  }
  // A nested set or pack: we keep the bytes, and must not pretend otherwise.
  EXPECT_TRUE(std::holds_alternative<std::monostate>(v));
  EXPECT_FALSE(item.raw.empty());
  return false;
}

void CompareWithGold(const std::string& ts_name, const std::string& gold_name,
                     std::map<int, int> expected_packets, Tally* tally) {
  SAKER_REQUIRE_TEST_DATA(ts_path, ts_name);
  SAKER_REQUIRE_TEST_DATA(gold_path, gold_name);
  std::ifstream in(gold_path);
  const json gold = json::parse(in);
  const auto decoded = DecodeFile(ts_path);

  std::map<int, std::vector<const json*>> gold_by_stream;
  for (const auto& entry : gold) {
    gold_by_stream[entry.at("stream-index").get<int>()].push_back(&entry);
  }
  for (const auto& [stream, count] : expected_packets) {
    ASSERT_EQ(static_cast<int>(gold_by_stream[stream].size()), count) << "gold stream " << stream;
    ASSERT_TRUE(decoded.contains(stream)) << "no packets decoded on stream " << stream;
    ASSERT_EQ(static_cast<int>(decoded.at(stream).size()), count) << "stream " << stream;
  }
  for (const auto& [stream, packets] : decoded) {
    EXPECT_TRUE(expected_packets.contains(stream) || packets.empty()) << "stream " << stream;
  }

  for (const auto& [stream, count] : expected_packets) {
    for (int i = 0; i < count; ++i) {
      SCOPED_TRACE(ts_name + " stream " + std::to_string(stream) + " packet " + std::to_string(i));
      const DecodedPacket& ours = decoded.at(stream)[static_cast<size_t>(i)];
      const json& theirs = *gold_by_stream[stream][static_cast<size_t>(i)];
      ASSERT_EQ(ours.kind, PacketKind::kSt0601);
      ASSERT_TRUE(ours.status.ok()) << ours.status.ToString();
      EXPECT_EQ(ours.key.ToHex(), theirs.at("key").at("hex").get<std::string>());
      ASSERT_TRUE(ours.st0601.has_value());
      const St0601Set& set = *ours.st0601;
      EXPECT_TRUE(set.checksum_ok)
          << "stored " << set.stored_checksum.value_or(0) << " computed " << set.computed_checksum;
      EXPECT_TRUE(set.warnings.empty()) << set.warnings.front();
      ASSERT_TRUE(ours.metadata.has_value());
      EXPECT_TRUE(ours.metadata->checksum_ok);

      // KWIVER lists a set's tags sorted and drops the checksum; sort ours
      // the same way (stable, so repeated tags keep their order).
      std::vector<const St0601Item*> items;
      for (const auto& item : set.items) {
        if (item.tag != 1) items.push_back(&item);
      }
      std::stable_sort(items.begin(), items.end(),
                       [](const St0601Item* a, const St0601Item* b) { return a->tag < b->tag; });
      const json& gold_items = theirs.at("value");
      std::vector<uint32_t> our_tags, gold_tags;
      for (const auto* item : items) our_tags.push_back(item->tag);
      for (const auto& item : gold_items) gold_tags.push_back(item.at("key").at("integer"));
      ASSERT_EQ(our_tags, gold_tags);
      for (size_t k = 0; k < items.size(); ++k) {
        if (CompareItem(*items[k], gold_items[k].at("value"))) {
          ++tally->compared_values;
        } else {
          ++tally->raw_only;
        }
      }
      ++tally->packets;
    }
  }
}

TEST(KwiverConformanceTest, H264Klv) {
  Tally tally;
  CompareWithGold("kwiver/h264_klv.ts", "kwiver/video_stream_klv.json", {{1, 30}}, &tally);
  if (HasFatalFailure() || IsSkipped()) return;
  std::cout << "[ figures  ] h264_klv.ts: " << tally.packets << " packets compared, "
            << tally.compared_values << " tag values compared, " << tally.raw_only
            << " nested/packed values kept raw\n";
  EXPECT_EQ(tally.packets, 30);
  EXPECT_GE(tally.compared_values, 30 * 110);
}

TEST(KwiverConformanceTest, H265TrickyKlv) {
  Tally tally;
  CompareWithGold("kwiver/h265_tricky_klv.ts", "kwiver/video_stream_tricky_klv.json",
                  {{1, 30}, {2, 60}}, &tally);
  if (HasFatalFailure() || IsSkipped()) return;
  std::cout << "[ figures  ] h265_tricky_klv.ts: " << tally.packets << " packets compared, "
            << tally.compared_values << " tag values compared, " << tally.raw_only
            << " nested/packed values kept raw\n";
  EXPECT_EQ(tally.packets, 90);
  EXPECT_GE(tally.compared_values, 30 * 110 + 60 * 3);
}

// The same KLV bytes are muxed with other codecs; the reader and the decoder
// must not care.
TEST(KwiverConformanceTest, SameKlvInOtherContainers) {
  SAKER_REQUIRE_TEST_DATA(h264, "kwiver/h264_klv.ts");
  const auto reference = DecodeFile(h264);
  for (const char* name : {"kwiver/mpeg2_klv.ts", "kwiver/h265_klv.ts"}) {
    SCOPED_TRACE(name);
    auto path = saker::testing::FindTestData(name);
    if (!path) GTEST_SKIP() << name << " not found";
    const auto decoded = DecodeFile(*path);
    ASSERT_TRUE(decoded.contains(1));
    ASSERT_EQ(decoded.at(1).size(), reference.at(1).size());
    for (size_t i = 0; i < decoded.at(1).size(); ++i) {
      EXPECT_EQ(decoded.at(1)[i].raw, reference.at(1)[i].raw) << "packet " << i;
      EXPECT_TRUE(decoded.at(1)[i].st0601->checksum_ok);
    }
  }
}

TEST(KwiverConformanceTest, FileWithoutKlv) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_no_klv.ts");
  const auto decoded = DecodeFile(path);
  size_t packets = 0;
  for (const auto& [stream, list] : decoded) packets += list.size();
  EXPECT_EQ(packets, 0u);
}

}  // namespace
}  // namespace saker::klv
