// MISB ST 0601 encoding: ST 1201 IMAPB forward mapping, every numeric,
// integer and text tag through St0601Encoder and back through DecodeSt0601,
// byte-exact re-encoding of the real packets of the shared data folder, and
// the errors the encoder must report instead of writing a bad packet.

#include "core/klv/st0601_encode.h"

#include "core/klv/decode.h"
#include "core/klv/st0601.h"
#include "core/klv/st0601_tags.h"
#include "core/klv/st1201.h"
#include "tests/core/klv/klv_test_util.h"
#include "tests/core/klv/ts_extract.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <iostream>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace saker::klv {
namespace {

using internal::FindTagSpec;
using internal::Mapping;
using internal::TagSpec;
using testing::HexBytes;
using testing::MakeSt0601Packet;
using testing::Tlv;

constexpr uint64_t kTime = 1231798102000000;  // 2009-01-12T22:08:22Z, the MISB example's
constexpr uint64_t kLsVersion = 17;

// An encoder holding the two mandatory items, so a test can add the one it
// is about.
St0601Encoder WithMandatoryItems() {
  St0601Encoder e;
  e.AddUnsigned(2, kTime).AddUnsigned(65, kLsVersion);
  return e;
}

// Splits and decodes encoder output, which must be exactly one packet with a
// valid checksum and nothing to warn about.
St0601Set DecodeOnePacket(const StatusOr<std::vector<uint8_t>>& bytes) {
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  if (!bytes.ok()) return {};
  const KlvSplitResult split = SplitKlvPackets(*bytes);
  EXPECT_TRUE(split.errors.empty()) << split.errors.front();
  EXPECT_EQ(split.skipped_bytes, 0u);
  if (split.packets.size() != 1) {
    ADD_FAILURE() << split.packets.size() << " packets";
    return {};
  }
  EXPECT_EQ(split.packets[0].key, kSt0601Key);
  auto set = DecodeSt0601(split.packets[0]);
  EXPECT_TRUE(set.ok()) << set.status().ToString();
  if (!set.ok()) return {};
  EXPECT_TRUE(set->checksum_ok);
  EXPECT_TRUE(set->warnings.empty()) << set->warnings.front();
  EXPECT_FALSE(set->items.empty());
  if (!set->items.empty()) {
    EXPECT_EQ(set->items.back().tag, 1u) << "checksum last";
  }
  return *set;
}

// The one item with `tag` (failing the test when there is none).
St0601Item ItemOf(const St0601Set& set, uint32_t tag) {
  const St0601Item* item = set.Find(tag);
  if (item == nullptr) {
    ADD_FAILURE() << "no tag " << tag << " in the set";
    return {};
  }
  return *item;
}

// The error message of a Finish() that must fail.
std::string ErrorOf(const St0601Encoder& e) {
  const auto result = e.Finish();
  EXPECT_FALSE(result.ok()) << "Finish() succeeded";
  if (result.ok()) return "";
  EXPECT_EQ(result.status().code(), StatusCode::kInvalidArgument);
  return result.status().message();
}

void ExpectMentions(const std::string& message, std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
  }
}

std::vector<uint32_t> Range(uint32_t first, uint32_t last) {
  std::vector<uint32_t> tags;
  for (uint32_t tag = first; tag <= last; ++tag) tags.push_back(tag);
  return tags;
}

std::vector<uint32_t> Join(std::initializer_list<std::vector<uint32_t>> parts) {
  std::vector<uint32_t> all;
  for (const auto& part : parts) all.insert(all.end(), part.begin(), part.end());
  return all;
}

// The lengths an integer tag allows: 1..length when variable, else length.
std::vector<size_t> LengthsOf(const TagSpec& spec) {
  if (!spec.variable_length) return {spec.length};
  std::vector<size_t> lengths;
  for (size_t n = 1; n <= spec.length; ++n) lengths.push_back(n);
  return lengths;
}

// What a double cannot resolve around values of this range: the long IMAPB
// forms (7 and 8 bytes) have codes finer than the spacing of doubles there,
// so "within one code" can only hold up to this much more.
double DoubleNoise(double x, double min, double max) {
  return 4 * DBL_EPSILON * (std::abs(x) + std::abs(min) + std::abs(max));
}

std::vector<uint32_t> TagsWithMapping(Mapping mapping) {
  std::vector<uint32_t> tags;
  for (uint32_t tag = 1; tag <= internal::kMaxSt0601Tag; ++tag) {
    if (FindTagSpec(tag)->mapping == mapping) tags.push_back(tag);
  }
  return tags;
}

// ---------------------------------------------------------------------------
// ST 1201 IMAPB

TEST(St1201EncodeTest, KnownCodes) {
  // The decoder's vectors (KWIVER's exhaustive packet), the other way round.
  EXPECT_EQ(*EncodeImapb(-900, 40000, 3, 23456.234375), HexBytes("2f921e"));
  EXPECT_EQ(*EncodeImapb(0, 21000, 3, 1.625), HexBytes("0001a0"));
  EXPECT_EQ(*EncodeImapb(-1000, 1000, 2, 1.0), HexBytes("3e90"));
  EXPECT_EQ(*EncodeImapb(-1000, 1000, 3, 0.004150390625), HexBytes("3e8011"));
  EXPECT_EQ(*EncodeImapb(1, 99999, 3, 2400), HexBytes("0257c0"));
  EXPECT_EQ(*EncodeImapb(0, 100, 2, 0), HexBytes("0000"));
  EXPECT_EQ(*EncodeImapb(-900, 40000, 3, -900), HexBytes("000000"));
  // A fractional zero offset: zero is code 4916 (0x1334) and exact.
  EXPECT_EQ(*EncodeImapb(-0.3, 1, 2, 0.0), HexBytes("1334"));
  // The top of a range that fills its power of two is the MSB-alone code,
  // the largest normal one (never a special value).
  EXPECT_EQ(*EncodeImapb(0, 256, 2, 256), HexBytes("8000"));
  // Round to nearest, not ST 1201's floor: one code is 2^-7 m here.
  EXPECT_EQ(*EncodeImapb(-900, 40000, 3, -900 + 0.75 / 128), HexBytes("000001"));
  EXPECT_EQ(*EncodeImapb(-900, 40000, 3, -900 + 0.25 / 128), HexBytes("000000"));
}

TEST(St1201EncodeTest, RoundTripsWithinHalfACode) {
  std::mt19937 rng(1201);
  const std::pair<double, double> ranges[] = {{0, 1500000}, {-900, 40000}, {0, 21000},
                                              {0, 360},     {-1000, 1000}, {0, 100},
                                              {1, 99999},   {-0.3, 1},     {-19.2, 19.2}};
  int checked = 0;
  for (const auto& [min, max] : ranges) {
    std::uniform_real_distribution<double> value(min, max);
    for (size_t length = 1; length <= 8; ++length) {
      SCOPED_TRACE("[" + std::to_string(min) + ", " + std::to_string(max) + "] in " +
                   std::to_string(length) + " bytes");
      const double step = ImapbResolution(min, max, length);
      std::vector<double> values = {min, max, (min + max) / 2};
      if (min < 0 && max > 0) values.insert(values.end(), {0.0, -step / 3, step / 3});
      for (int i = 0; i < 50; ++i) values.push_back(value(rng));
      for (double x : values) {
        auto bytes = EncodeImapb(min, max, length, x);
        ASSERT_TRUE(bytes.ok()) << x << ": " << bytes.status().ToString();
        ASSERT_EQ(bytes->size(), length);
        auto back = DecodeImapb(min, max, *bytes);
        ASSERT_TRUE(back.ok());
        ASSERT_TRUE(std::isfinite(*back)) << x << " became a special value";
        EXPECT_LE(std::abs(*back - x), step / 2 * (1 + 1e-9) + DoubleNoise(x, min, max)) << x;
        // Re-encoding the decoded value gives the same code, as long as
        // the code is coarser than a double's resolution of the value.
        // (A code below the range, possible with a fractional zero offset,
        // comes from the range's minimum.)
        if (step > 1e-12 * (max - min)) {
          EXPECT_EQ(*EncodeImapb(min, max, length, std::clamp(*back, min, max)), *bytes) << x;
        }
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 9 * 8 * 50);
}

TEST(St1201EncodeTest, Errors) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(EncodeImapb(0, 100, 2, nan).ok());
  EXPECT_FALSE(EncodeImapb(0, 100, 2, inf).ok());
  EXPECT_FALSE(EncodeImapb(0, 100, 2, -inf).ok());
  EXPECT_FALSE(EncodeImapb(0, 100, 2, -0.001).ok()) << "below min: never clamped";
  EXPECT_FALSE(EncodeImapb(0, 100, 2, 100.001).ok()) << "above max: never clamped";
  EXPECT_FALSE(EncodeImapb(0, 100, 0, 1).ok());
  EXPECT_FALSE(EncodeImapb(0, 100, 9, 1).ok());
  EXPECT_FALSE(EncodeImapb(100, 0, 2, 1).ok());
  EXPECT_FALSE(EncodeImapb(0, nan, 2, 1).ok());
  ExpectMentions(EncodeImapb(0, 100, 2, 100.5).status().message(), {"100.5", "[0, 100]"});
}

// ---------------------------------------------------------------------------
// Every tag, through the encoder and back

// The tags of each kind, stated here independently of the table so that a
// change to the table is noticed.
const std::vector<uint32_t> kUnsignedMapTags = Join({{5},
                                                     Range(15, 18),
                                                     Range(20, 22),
                                                     {25},
                                                     Range(35, 38),
                                                     Range(42, 46),
                                                     {49},
                                                     Range(53, 55),
                                                     {57, 58, 64, 69, 71, 75, 76, 78}});
const std::vector<uint32_t> kSignedMapTags = Join({{6, 7, 13, 14, 19, 23, 24},
                                                   Range(26, 33),
                                                   {40, 41},
                                                   Range(50, 52),
                                                   {67, 68, 79, 80},
                                                   Range(82, 93)});
const std::vector<uint32_t> kImapbTags =
    Join({{96}, Range(103, 105), {109}, Range(112, 114), Range(117, 120), {132, 134}});
const std::vector<uint32_t> kUintTags = Join(
    {{2, 8, 9, 34, 47, 56}, Range(60, 63), {65, 72, 77, 110, 111}, Range(123, 126), {131, 133}});
const std::vector<uint32_t> kIntTags = {39, 136, 137};
const std::vector<uint32_t> kTextTags = {3, 4, 10, 11, 12, 59, 70, 106, 107, 108, 129, 135};

TEST(St0601EncodeTest, TagKindsAreTheExpectedOnes) {
  EXPECT_EQ(TagsWithMapping(Mapping::kUnsignedMap), kUnsignedMapTags);
  EXPECT_EQ(TagsWithMapping(Mapping::kSignedMap), kSignedMapTags);
  EXPECT_EQ(TagsWithMapping(Mapping::kImapb), kImapbTags);
  EXPECT_EQ(TagsWithMapping(Mapping::kUint), kUintTags);
  EXPECT_EQ(TagsWithMapping(Mapping::kInt), kIntTags);
  EXPECT_EQ(TagsWithMapping(Mapping::kString), kTextTags);
  EXPECT_EQ(kUnsignedMapTags.size() + kSignedMapTags.size() + kImapbTags.size(), 30u + 36u + 14u);
  EXPECT_EQ(kUintTags.size() + kIntTags.size() + kTextTags.size(), 21u + 3u + 12u);
}

// Values across a numeric tag's range: both ends, the middle, values near
// zero and negative ones where the range has them, values a third of a code
// from the ends, and random ones.
std::vector<double> ValuesAcross(double low, double high, double step, std::mt19937* rng) {
  std::vector<double> values = {low, high, (low + high) / 2, low + step / 3, high - step / 3};
  if (low <= 0 && high >= 0) {
    values.insert(values.end(), {0.0, step / 3, 1e-9});
    if (low < 0) values.insert(values.end(), {-step / 3, -1e-9, low / 2, low / 3 + step / 7});
  }
  std::uniform_real_distribution<double> uniform(low, high);
  for (int i = 0; i < 30; ++i) values.push_back(uniform(*rng));
  return values;
}

TEST(St0601EncodeTest, EveryNumericTagRoundTripsWithinOneLsb) {
  std::mt19937 rng(601);
  int checked = 0;
  std::set<uint32_t> covered;
  for (uint32_t tag : Join({kUnsignedMapTags, kSignedMapTags, kImapbTags})) {
    const TagSpec& spec = *FindTagSpec(tag);
    const double low = spec.mapping == Mapping::kSignedMap ? -spec.max : spec.min;
    // Fixed-point tags have one length; IMAPB tags every length they allow,
    // with 0 standing for the tag's standard length.
    std::vector<size_t> lengths = {0};
    if (spec.mapping == Mapping::kImapb) {
      for (size_t n = 1; n <= spec.length; ++n) lengths.push_back(n);
    }
    for (size_t length : lengths) {
      const size_t expected_length =
          length != 0 ? length
                      : (spec.mapping == Mapping::kImapb ? spec.default_length : spec.length);
      const double lsb = St0601Resolution(tag, expected_length).value_or(0);
      ASSERT_GT(lsb, 0) << tag;
      for (double x : ValuesAcross(low, spec.max, lsb, &rng)) {
        SCOPED_TRACE("tag " + std::to_string(tag) + " (" + spec.name + "), length " +
                     std::to_string(length) + ", value " + std::to_string(x));
        St0601Encoder e = WithMandatoryItems();
        e.Add(tag, x, length);
        const St0601Set set = DecodeOnePacket(e.Finish());
        const St0601Item item = ItemOf(set, tag);
        ASSERT_EQ(item.raw.size(), expected_length);
        ASSERT_TRUE(std::holds_alternative<double>(item.value));
        const double back = std::get<double>(item.value);
        const double noise = DoubleNoise(x, spec.min, spec.max);
        EXPECT_NEAR(back, x, lsb + noise) << "within one LSB";
        // Rounding to the nearest code, the promise of the encoder, is
        // tighter: half a code (a floor would be off by up to a whole one).
        EXPECT_LE(std::abs(back - x), lsb / 2 * (1 + 1e-9) + noise) << "round to nearest";
        ++checked;
        covered.insert(tag);
      }
    }
  }
  EXPECT_EQ(covered.size(), 80u);
  std::cout << "[ figures  ] " << covered.size() << " numeric tags, " << checked
            << " values encoded and decoded\n";
}

TEST(St0601EncodeTest, LimitsOfTheFixedPointMappings) {
  // The codes of the ends and of zero, as ST 0601 defines them.
  auto raw = [](uint32_t tag, double value) {
    St0601Encoder e = WithMandatoryItems();
    e.Add(tag, value);
    return ItemOf(DecodeOnePacket(e.Finish()), tag).raw;
  };
  EXPECT_EQ(raw(13, 90), HexBytes("7FFFFFFF"));
  EXPECT_EQ(raw(13, -90), HexBytes("80000001"));
  EXPECT_EQ(raw(13, 0), HexBytes("00000000"));
  EXPECT_EQ(raw(14, -180), HexBytes("80000001"));
  EXPECT_EQ(raw(26, 0.075), HexBytes("7FFF"));
  EXPECT_EQ(raw(26, -0.075), HexBytes("8001"));
  EXPECT_EQ(raw(5, 0), HexBytes("0000"));
  EXPECT_EQ(raw(5, 360), HexBytes("FFFF"));
  EXPECT_EQ(raw(15, -900), HexBytes("0000"));
  EXPECT_EQ(raw(15, 19000), HexBytes("FFFF"));
  // The MISB ST 0902 example values (klvdata/DynamicOnlyMISMMSPacketData.bin).
  EXPECT_EQ(raw(5, 159.974365), HexBytes("71C2"));
  EXPECT_EQ(raw(13, 60.176822966978335), HexBytes("5595B66D"));
}

TEST(St0601EncodeTest, IntegerTagsRoundTripExactly) {
  std::mt19937_64 rng(602);
  int checked = 0;
  for (uint32_t tag : kUintTags) {
    const TagSpec& spec = *FindTagSpec(tag);
    for (size_t length : LengthsOf(spec)) {
      const uint64_t top = length == 8 ? ~uint64_t{0} : (uint64_t{1} << (8 * length)) - 1;
      for (uint64_t v : {uint64_t{0}, uint64_t{1}, top, rng() & top}) {
        SCOPED_TRACE("tag " + std::to_string(tag) + " length " + std::to_string(length) +
                     " value " + std::to_string(v));
        St0601Encoder e;
        if (tag != 2) e.AddUnsigned(2, kTime);
        if (tag != 65) e.AddUnsigned(65, kLsVersion);
        e.AddUnsigned(tag, v, length);
        const St0601Item item = ItemOf(DecodeOnePacket(e.Finish()), tag);
        EXPECT_EQ(item.raw.size(), length);
        ASSERT_TRUE(std::holds_alternative<uint64_t>(item.value));
        EXPECT_EQ(std::get<uint64_t>(item.value), v);
        ++checked;
      }
    }
  }
  for (uint32_t tag : kIntTags) {
    const TagSpec& spec = *FindTagSpec(tag);
    for (size_t length : LengthsOf(spec)) {
      const int64_t top =
          length == 8 ? std::numeric_limits<int64_t>::max() : (int64_t{1} << (8 * length - 1)) - 1;
      const int64_t bottom = -top - 1;
      for (int64_t v : {bottom, int64_t{-1}, int64_t{0}, int64_t{1}, top}) {
        SCOPED_TRACE("tag " + std::to_string(tag) + " length " + std::to_string(length) +
                     " value " + std::to_string(v));
        St0601Encoder e = WithMandatoryItems();
        e.AddSigned(tag, v, length);
        const St0601Item item = ItemOf(DecodeOnePacket(e.Finish()), tag);
        EXPECT_EQ(item.raw.size(), length);
        ASSERT_TRUE(std::holds_alternative<int64_t>(item.value));
        EXPECT_EQ(std::get<int64_t>(item.value), v);
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(St0601EncodeTest, IntegerStandardLengths) {
  auto length_of = [](auto add) {
    St0601Encoder e = WithMandatoryItems();
    add(e);
    const St0601Set set = DecodeOnePacket(e.Finish());
    return set.items.size() == 4 ? set.items[2].raw.size() : 0;
  };
  // Fixed-length tags take their length whatever the value.
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(72, 5); }), 8u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(60, 5); }), 2u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(39, -10); }), 1u);
  // Variable-length tags take the shortest form that holds the value.
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(110, 0); }), 1u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(110, 255); }), 1u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(110, 256); }), 2u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddUnsigned(131, 1529588637122999); }), 7u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(136, -1); }), 1u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(136, 127); }), 1u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(136, 128); }), 2u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(136, -129); }), 2u);
  EXPECT_EQ(length_of([](St0601Encoder& e) { e.AddSigned(137, 5025678901); }), 5u);
}

TEST(St0601EncodeTest, TextTagsRoundTrip) {
  int checked = 0;
  for (uint32_t tag : kTextTags) {
    const size_t longest = FindTagSpec(tag)->length;
    EXPECT_EQ(longest, tag == 129 ? 32u : 127u);
    for (const std::string& text :
         {std::string("Mission 12"), std::string(longest, 'x'), std::string("Z\xC3\xBCrich"),
          std::string("a\0b", 3), std::string(1, '\xFF')}) {
      SCOPED_TRACE("tag " + std::to_string(tag) + " text of " + std::to_string(text.size()));
      St0601Encoder e = WithMandatoryItems();
      e.AddString(tag, text);
      const St0601Item item = ItemOf(DecodeOnePacket(e.Finish()), tag);
      ASSERT_TRUE(std::holds_alternative<std::string>(item.value));
      EXPECT_EQ(std::get<std::string>(item.value), text);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 12 * 5);
}

TEST(St0601EncodeTest, AbsentIsTheIndicatorOrAZeroLengthItem) {
  int indicators = 0, empty_items = 0;
  for (uint32_t tag = 3; tag <= internal::kMaxSt0601Tag; ++tag) {
    if (tag == 65) continue;  // mandatory, tested below
    SCOPED_TRACE("tag " + std::to_string(tag) + " (" + St0601TagName(tag) + ")");
    const TagSpec& spec = *FindTagSpec(tag);
    St0601Encoder e = WithMandatoryItems();
    e.AddAbsent(tag);
    const St0601Item item = ItemOf(DecodeOnePacket(e.Finish()), tag);
    if (spec.mapping == Mapping::kSignedMap) {
      std::vector<uint8_t> indicator(spec.length, 0x00);
      indicator[0] = 0x80;
      EXPECT_EQ(item.raw, indicator);
      ++indicators;
    } else {
      EXPECT_TRUE(item.raw.empty());
      ++empty_items;
    }
    if (spec.mapping == Mapping::kRaw) {
      EXPECT_TRUE(std::holds_alternative<std::monostate>(item.value)) << "raw tags stay raw";
    } else {
      EXPECT_TRUE(std::holds_alternative<Absent>(item.value));
    }
  }
  EXPECT_EQ(indicators, 36);
  EXPECT_EQ(empty_items, 140 - 36);
  // The mandatory items need a value: "unknown" does not count.
  St0601Encoder no_time;
  no_time.AddAbsent(2).AddUnsigned(65, kLsVersion);
  ExpectMentions(ErrorOf(no_time), {"tag 2 (Precision Time Stamp)", "mandatory"});
  St0601Encoder no_version;
  no_version.AddUnsigned(2, kTime).AddAbsent(65);
  ExpectMentions(ErrorOf(no_version), {"tag 65 (UAS Datalink LS Version Number)", "mandatory"});
}

TEST(St0601EncodeTest, RawItemsAndBerOidTags) {
  std::vector<uint8_t> nested = HexBytes("01 01 01 02 01 07 03 05 2F 2F 55 53 41");
  std::vector<uint8_t> big(600);
  for (size_t i = 0; i < big.size(); ++i) big[i] = static_cast<uint8_t>(i * 7);
  St0601Encoder e = WithMandatoryItems();
  e.AddRaw(48, nested)
      .AddRaw(74, big)
      .AddRaw(100, {})
      .AddRaw(100, HexBytes("0d04 5595b66d"))  // Segment sets may repeat
      .AddRaw(144, HexBytes("aa"))
      .AddRaw(16383, HexBytes("bb"))
      .AddRaw(16384, HexBytes("cc"))
      .AddRaw((1u << 28) - 1, HexBytes("dd"))
      .AddRaw(5, HexBytes("010203"));  // a wrong length, which the decoder keeps raw
  const auto bytes = e.Finish();
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  const KlvSplitResult split = SplitKlvPackets(*bytes);
  ASSERT_EQ(split.packets.size(), 1u);
  auto set = DecodeSt0601(split.packets[0]);
  ASSERT_TRUE(set.ok());
  EXPECT_TRUE(set->checksum_ok);
  ASSERT_EQ(set->warnings.size(), 1u) << "only the wrong-length tag 5";
  EXPECT_NE(set->warnings[0].find("tag 5"), std::string::npos);
  std::vector<uint32_t> tags;
  for (const auto& item : set->items) tags.push_back(item.tag);
  const std::vector<uint32_t> expected = {
      2, 65, 48, 74, 100, 100, 144, 16383, 16384, (1u << 28) - 1, 5, 1};
  EXPECT_EQ(tags, expected);
  EXPECT_EQ(set->items[2].raw, nested);
  EXPECT_EQ(set->items[3].raw, big);
  EXPECT_TRUE(set->items[4].raw.empty());
  for (size_t i = 2; i + 1 < set->items.size(); ++i) {
    EXPECT_TRUE(std::holds_alternative<std::monostate>(set->items[i].value)) << i;
  }
  // BER-OID tags and a long-form item length, as bytes.
  auto contains = [&](const std::vector<uint8_t>& needle) {
    return std::search(bytes->begin(), bytes->end(), needle.begin(), needle.end()) != bytes->end();
  };
  EXPECT_TRUE(contains(HexBytes("4a 82 0258 00 07 0e")));  // tag 74, length 600
  EXPECT_TRUE(contains(HexBytes("81 10 01 aa")));          // tag 144
  EXPECT_TRUE(contains(HexBytes("ff 7f 01 bb")));          // tag 16383
  EXPECT_TRUE(contains(HexBytes("81 80 00 01 cc")));       // tag 16384
  EXPECT_TRUE(contains(HexBytes("ff ff ff 7f 01 dd")));    // tag 2^28 - 1
}

TEST(St0601EncodeTest, PacketLayoutAndChecksum) {
  // Built by hand with the test helpers, which share no code with the
  // encoder: key, shortest BER length, items in order, checksum last.
  const auto items = HexBytes("0208 00046050584E0180 4101 11 0b04 454f2031");
  St0601Encoder e;
  e.AddUnsigned(2, 0x00046050584E0180).AddUnsigned(65, 0x11).AddString(11, "EO 1");
  const auto bytes = e.Finish();
  ASSERT_TRUE(bytes.ok());
  EXPECT_EQ(*bytes, MakeSt0601Packet(items).bytes);
  EXPECT_EQ(bytes->at(16), bytes->size() - 17) << "short-form length";
  EXPECT_EQ(e.Finish().value(), *bytes) << "Finish() can be called again";

  // Long-form packet lengths: one, two and three length bytes.
  for (size_t filler : {150u, 300u, 70000u}) {
    SCOPED_TRACE(filler);
    St0601Encoder long_packet = WithMandatoryItems();
    long_packet.AddRaw(74, std::vector<uint8_t>(filler, 0x5A));
    const auto long_bytes = long_packet.Finish();
    ASSERT_TRUE(long_bytes.ok());
    // Items: time stamp (1 + 1 + 8), version (1 + 1 + 1), tag 74 with its
    // BER length, the checksum (1 + 1 + 2).
    const size_t value_size = 10 + 3 + 1 + testing::BerLength(filler).size() + filler + 4;
    const uint8_t expected_form = value_size < 256 ? 0x81 : value_size < 65536 ? 0x82 : 0x83;
    EXPECT_EQ(long_bytes->at(16), expected_form);
    EXPECT_EQ(long_bytes->size(), 16 + 1 + (expected_form & 0x0F) + value_size);
    const St0601Set set = DecodeOnePacket(long_bytes);
    EXPECT_EQ(ItemOf(set, 74).raw.size(), filler);
    // The checksum covers everything up to its own length byte.
    const uint16_t bcc = Bcc16(ByteSpan(*long_bytes).first(long_bytes->size() - 2));
    EXPECT_EQ(set.stored_checksum.value_or(0), bcc);
  }
}

TEST(St0601EncodeTest, ChainedCallsBuildOnePacket) {
  St0601Encoder e;
  e.AddUnsigned(2, kTime)
      .AddString(3, "Saker sim")
      .Add(5, 159.974)
      .Add(6, -0.43)
      .Add(7, 3.41)
      .Add(13, 38.252336)
      .Add(14, -77.366859)
      .Add(15, 1054.4)
      .Add(16, 12.5)
      .Add(17, 7.03)
      .Add(18, 0)
      .Add(19, -37.2)
      .Add(20, 0)
      .Add(21, 1750.25)
      .Add(23, 38.2455872)
      .Add(24, -77.3537377)
      .Add(25, 40.2)
      .Add(82, 38.2456129)
      .Add(83, -77.3535250)
      .Add(84, 38.2457)
      .Add(85, -77.3510)
      .Add(86, 38.2441)
      .Add(87, -77.3508)
      .Add(88, 38.2440)
      .Add(89, -77.3538)
      .Add(104, 1066.87)
      .AddUnsigned(65, kLsVersion);
  const auto bytes = e.Finish();
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  const KlvSplitResult split = SplitKlvPackets(*bytes);
  ASSERT_EQ(split.packets.size(), 1u);
  const DecodedPacket decoded = DecodePacket(split.packets[0]);
  ASSERT_TRUE(decoded.status.ok());
  ASSERT_TRUE(decoded.metadata.has_value());
  const FrameMetadata& m = *decoded.metadata;
  EXPECT_TRUE(m.checksum_ok);
  EXPECT_EQ(m.unix_time_us.value_or(0), kTime);
  EXPECT_EQ(m.mission_id.value_or(""), "Saker sim");
  EXPECT_EQ(m.ls_version.value_or(0), 17u);
  EXPECT_NEAR(*m.sensor_latitude_deg, 38.252336, 1e-7);
  EXPECT_NEAR(*m.sensor_longitude_deg, -77.366859, 1e-7);
  EXPECT_NEAR(*m.sensor_altitude_m, 1054.4, 0.16);
  EXPECT_NEAR(*m.sensor_rel_elevation_deg, -37.2, 1e-7);
  ASSERT_TRUE(m.corners.has_value());
  EXPECT_NEAR((*m.corners)[0].latitude_deg, 38.2456129, 1e-7);
  EXPECT_NEAR((*m.corners)[3].longitude_deg, -77.3538, 1e-7);
}

// ---------------------------------------------------------------------------
// Errors

TEST(St0601EncodeTest, OutOfRangeValuesAreErrorsNeverClamped) {
  const std::pair<uint32_t, double> cases[] = {
      {13, 90.5},   {13, -90.0000001}, {14, 180.01}, {5, -0.01},     {5, 360.01},
      {26, 0.0751}, {15, -900.5},      {36, 100.5},  {113, 40000.5}, {112, -1e-9}};
  for (const auto& [tag, value] : cases) {
    SCOPED_TRACE("tag " + std::to_string(tag) + " value " + std::to_string(value));
    St0601Encoder e = WithMandatoryItems();
    e.Add(tag, value);
    ExpectMentions(ErrorOf(e), {"tag " + std::to_string(tag) + " (" + St0601TagName(tag) + ")",
                                "out of the mapping's range"});
  }
  St0601Encoder e = WithMandatoryItems();
  e.Add(13, 90.5);
  ExpectMentions(ErrorOf(e), {"item 3, tag 13 (Sensor Latitude)", "value 90.5", "[-90, 90]"});
}

TEST(St0601EncodeTest, NonFiniteValuesAreErrors) {
  for (double value :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
        -std::numeric_limits<double>::infinity()}) {
    for (uint32_t tag : {13u, 5u, 112u}) {
      St0601Encoder e = WithMandatoryItems();
      e.Add(tag, value);
      ExpectMentions(ErrorOf(e), {"tag " + std::to_string(tag), "not a finite number"});
    }
  }
  St0601Encoder e = WithMandatoryItems();
  e.Add(13, std::numeric_limits<double>::quiet_NaN());
  ExpectMentions(ErrorOf(e), {"tag 13 (Sensor Latitude)", "nan"});
}

TEST(St0601EncodeTest, WrongTypeForTheTag) {
  struct Case {
    uint32_t tag;
    std::function<void(St0601Encoder&)> add;
    const char* says;
  };
  const Case cases[] = {
      {13, [](St0601Encoder& e) { e.AddString(13, "north"); }, "use Add)"},
      {13, [](St0601Encoder& e) { e.AddUnsigned(13, 5); }, "use Add)"},
      {13, [](St0601Encoder& e) { e.AddSigned(13, -5); }, "use Add)"},
      {72, [](St0601Encoder& e) { e.Add(72, 1.5); }, "use AddUnsigned"},
      {72, [](St0601Encoder& e) { e.AddSigned(72, 5); }, "use AddUnsigned"},
      {39, [](St0601Encoder& e) { e.AddUnsigned(39, 5); }, "use AddSigned"},
      {3, [](St0601Encoder& e) { e.Add(3, 12); }, "use AddString"},
      {48, [](St0601Encoder& e) { e.Add(48, 1); }, "use AddRaw"},
      {48, [](St0601Encoder& e) { e.AddString(48, "secret"); }, "use AddRaw"},
      {144, [](St0601Encoder& e) { e.Add(144, 1); }, "not an ST 0601.17 tag"},
      {144, [](St0601Encoder& e) { e.AddAbsent(144); }, "AddRaw"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.says);
    St0601Encoder e = WithMandatoryItems();
    c.add(e);
    ExpectMentions(ErrorOf(e),
                   {"tag " + std::to_string(c.tag) + " (" + St0601TagName(c.tag) + ")", c.says});
  }
}

TEST(St0601EncodeTest, ChecksumAddedByHand) {
  const std::function<void(St0601Encoder&)> adds[] = {
      [](St0601Encoder& e) { e.AddUnsigned(1, 0x1234); },
      [](St0601Encoder& e) { e.Add(1, 4660); },
      [](St0601Encoder& e) { e.AddRaw(1, HexBytes("1234")); },
      [](St0601Encoder& e) { e.AddAbsent(1); },
  };
  for (const auto& add : adds) {
    St0601Encoder e = WithMandatoryItems();
    add(e);
    ExpectMentions(ErrorOf(e), {"tag 1 (Checksum)", "computed by Finish()"});
  }
}

TEST(St0601EncodeTest, DuplicatesAndMandatoryItems) {
  St0601Encoder twice = WithMandatoryItems();
  twice.Add(13, 1).AddUnsigned(2, kTime + 1);
  ExpectMentions(ErrorOf(twice), {"item 4, tag 2 (Precision Time Stamp)", "twice"});
  St0601Encoder twice_13 = WithMandatoryItems();
  twice_13.Add(13, 1).AddAbsent(13);
  ExpectMentions(ErrorOf(twice_13), {"tag 13 (Sensor Latitude)", "twice"});
  St0601Encoder twice_raw = WithMandatoryItems();
  twice_raw.AddRaw(48, HexBytes("0101")).AddRaw(48, HexBytes("0101"));
  ExpectMentions(ErrorOf(twice_raw), {"tag 48 (Security Local Set)", "twice"});
  // Items ST 0601.17 allows more than once, and tags it does not define.
  St0601Encoder repeats = WithMandatoryItems();
  for (uint32_t tag : {100u, 101u, 102u, 115u, 200u}) {
    repeats.AddRaw(tag, HexBytes("00")).AddRaw(tag, HexBytes("01"));
  }
  EXPECT_TRUE(repeats.Finish().ok()) << repeats.Finish().status().ToString();

  St0601Encoder no_time;
  no_time.AddUnsigned(65, kLsVersion).Add(13, 1);
  ExpectMentions(ErrorOf(no_time), {"tag 2 (Precision Time Stamp)", "mandatory"});
  St0601Encoder no_version;
  no_version.AddUnsigned(2, kTime).Add(13, 1);
  ExpectMentions(ErrorOf(no_version), {"tag 65 (UAS Datalink LS Version Number)", "mandatory"});
  EXPECT_FALSE(St0601Encoder().Finish().ok());
}

TEST(St0601EncodeTest, BadLengthsAndTooLongText) {
  struct Case {
    uint32_t tag;
    std::function<void(St0601Encoder&)> add;
    const char* says;
  };
  const Case cases[] = {
      {13, [](St0601Encoder& e) { e.Add(13, 1, 2); }, "bad length 2: the tag takes exactly 4"},
      {72, [](St0601Encoder& e) { e.AddUnsigned(72, 5, 4); }, "exactly 8 bytes"},
      {8, [](St0601Encoder& e) { e.AddUnsigned(8, 300); }, "value 300 does not fit in 1 byte"},
      {110, [](St0601Encoder& e) { e.AddUnsigned(110, 70000, 2); }, "does not fit in 2 bytes"},
      {110, [](St0601Encoder& e) { e.AddUnsigned(110, 1, 5); }, "1 to 4 bytes"},
      {110, [](St0601Encoder& e) { e.AddUnsigned(110, uint64_t{1} << 32); }, "does not fit"},
      {136, [](St0601Encoder& e) { e.AddSigned(136, int64_t{1} << 40); }, "does not fit"},
      {39, [](St0601Encoder& e) { e.AddSigned(39, -129); }, "does not fit in 1 byte"},
      {109, [](St0601Encoder& e) { e.Add(109, 1, 5); }, "1 to 4 bytes"},
      {112, [](St0601Encoder& e) { e.Add(112, 1, 9); }, "1 to 8 bytes"},
      {3, [](St0601Encoder& e) { e.AddString(3, std::string(128, 'm')); },
       "of 128 bytes is longer than the 127"},
      {129, [](St0601Encoder& e) { e.AddString(129, std::string(33, 't')); }, "longer than the 32"},
      {3, [](St0601Encoder& e) { e.AddString(3, ""); }, "empty text"},
      {0, [](St0601Encoder& e) { e.AddRaw(0, HexBytes("00")); }, "tag 0 is not"},
      {1u << 28, [](St0601Encoder& e) { e.AddRaw(1u << 28, HexBytes("00")); }, "BER-OID"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.says);
    St0601Encoder e = WithMandatoryItems();
    c.add(e);
    ExpectMentions(ErrorOf(e), {"tag " + std::to_string(c.tag) + " (", c.says});
  }
}

TEST(St0601EncodeTest, TheFirstErrorIsReported) {
  St0601Encoder e = WithMandatoryItems();
  e.Add(5, 10).Add(13, 91).Add(14, 200).AddUnsigned(1, 0);
  const std::string message = ErrorOf(e);
  ExpectMentions(message, {"item 4, tag 13 (Sensor Latitude)", "value 91"});
  EXPECT_EQ(message.find("tag 14"), std::string::npos) << message;
}

// ---------------------------------------------------------------------------
// Byte-exact re-encoding of real packets

struct ReencodeTally {
  int packets = 0;
  int numbers = 0, integers = 0, texts = 0, absents = 0, raws = 0;
  int absents_kept_raw = 0;
};

// Re-encodes a decoded set from its decoded values, each item with its
// original length. The checksum item must be last, as the encoder writes it.
StatusOr<std::vector<uint8_t>> Reencode(const St0601Set& set, ReencodeTally* tally) {
  St0601Encoder e;
  for (size_t i = 0; i < set.items.size(); ++i) {
    const St0601Item& item = set.items[i];
    const size_t length = item.raw.size();
    if (item.tag == 1) {
      EXPECT_EQ(i + 1, set.items.size()) << "checksum not last";
      continue;
    }
    if (auto* d = std::get_if<double>(&item.value)) {
      e.Add(item.tag, *d, length);
      ++tally->numbers;
    } else if (auto* s = std::get_if<int64_t>(&item.value)) {
      e.AddSigned(item.tag, *s, length);
      ++tally->integers;
    } else if (auto* u = std::get_if<uint64_t>(&item.value)) {
      e.AddUnsigned(item.tag, *u, length);
      ++tally->integers;
    } else if (auto* text = std::get_if<std::string>(&item.value)) {
      e.AddString(item.tag, *text);
      ++tally->texts;
    } else if (std::holds_alternative<Absent>(item.value)) {
      // Absent has three spellings on the wire and AddAbsent writes one per
      // tag: the error indicator for signed fixed-point tags and a
      // zero-length item for the others. The remaining two, a zero-length
      // item on a signed fixed-point tag and an ST 1201 special value
      // (infinity, NaN) on an IMAPB tag, decode to the same Absent but cannot
      // come back from it, so they are reproduced raw.
      const bool signed_map = FindTagSpec(item.tag)->mapping == Mapping::kSignedMap;
      if (signed_map == !item.raw.empty()) {
        e.AddAbsent(item.tag);
        ++tally->absents;
      } else {
        e.AddRaw(item.tag, item.raw);
        ++tally->absents_kept_raw;
      }
    } else {
      e.AddRaw(item.tag, item.raw);
      ++tally->raws;
    }
  }
  return e.Finish();
}

// Re-encodes every ST 0601 packet of `units` (each one demuxed data unit)
// and compares it with the original bytes.
void ReencodeAll(const std::vector<std::vector<uint8_t>>& units, ReencodeTally* tally) {
  for (const auto& unit : units) {
    const KlvSplitResult split = SplitKlvPackets(unit);
    ASSERT_TRUE(split.errors.empty()) << split.errors.front();
    for (const KlvPacket& packet : split.packets) {
      SCOPED_TRACE("packet " + std::to_string(tally->packets));
      ASSERT_EQ(packet.key, kSt0601Key) << "the encoder writes this exact key";
      auto set = DecodeSt0601(packet);
      ASSERT_TRUE(set.ok()) << set.status().ToString();
      ASSERT_TRUE(set->checksum_ok);
      const auto bytes = Reencode(*set, tally);
      ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
      EXPECT_EQ(*bytes, packet.bytes) << "re-encoded packet differs";
      ++tally->packets;
    }
  }
}

std::vector<std::vector<uint8_t>> TsDataUnits(const std::filesystem::path& path) {
  std::string error;
  const auto streams = testing::ExtractTsStreams(saker::testing::ReadFileBytes(path), &error);
  EXPECT_TRUE(error.empty()) << error;
  std::vector<std::vector<uint8_t>> units;
  for (const auto& stream : streams)
    units.insert(units.end(), stream.units.begin(), stream.units.end());
  return units;
}

void PrintTally(const std::string& name, const ReencodeTally& t) {
  std::cout << "[ figures  ] " << name << ": " << t.packets
            << " packets byte-exact; items: " << t.numbers << " numbers, " << t.integers
            << " integers, " << t.texts << " texts, " << t.absents << " absent, " << t.raws
            << " raw, " << t.absents_kept_raw << " absent kept raw\n";
}

TEST(St0601ReencodeTest, KwiverH264Packets) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_klv.ts");
  ReencodeTally tally;
  ReencodeAll(TsDataUnits(path), &tally);
  PrintTally("h264_klv.ts", tally);
  EXPECT_EQ(tally.packets, 30);
  EXPECT_GE(tally.numbers + tally.integers + tally.texts, 30 * 110);
}

TEST(St0601ReencodeTest, KwiverH265TrickyPackets) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h265_tricky_klv.ts");
  ReencodeTally tally;
  ReencodeAll(TsDataUnits(path), &tally);
  PrintTally("h265_tricky_klv.ts", tally);
  EXPECT_EQ(tally.packets, 90);
}

TEST(St0601ReencodeTest, MisbExamplePackets) {
  SAKER_REQUIRE_TEST_DATA(dynamic_only, "klvdata/DynamicOnlyMISMMSPacketData.bin");
  SAKER_REQUIRE_TEST_DATA(dynamic_constant, "klvdata/DynamicConstantMISMMSPacketData.bin");
  ReencodeTally tally;
  ReencodeAll({saker::testing::ReadFileBytes(dynamic_only)}, &tally);
  PrintTally("DynamicOnlyMISMMSPacketData.bin", tally);
  EXPECT_EQ(tally.packets, 1);

  // The "dynamic and constant" example carries a stale checksum (0xAA43 where
  // the bytes give 0x3E1E). The encoder always writes the right one, so the
  // packet comes back identical except for those two bytes.
  const auto original = saker::testing::ReadFileBytes(dynamic_constant);
  const KlvSplitResult split = SplitKlvPackets(original);
  ASSERT_EQ(split.packets.size(), 1u);
  auto set = DecodeSt0601(split.packets[0]);
  ASSERT_TRUE(set.ok());
  ASSERT_FALSE(set->checksum_ok);
  ReencodeTally constant_tally;
  const auto bytes = Reencode(*set, &constant_tally);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  const std::vector<uint8_t>& packet = split.packets[0].bytes;
  ASSERT_EQ(bytes->size(), packet.size());
  EXPECT_TRUE(std::equal(bytes->begin(), bytes->end() - 2, packet.begin()));
  EXPECT_EQ(std::vector<uint8_t>(packet.end() - 2, packet.end()), HexBytes("AA43"));
  EXPECT_EQ(std::vector<uint8_t>(bytes->end() - 2, bytes->end()), HexBytes("3E1E"));
}

// The real packets hold no Absent item, so the three spellings of "no value"
// are checked on a hand-built packet.
TEST(St0601ReencodeTest, AbsentSpellings) {
  std::vector<uint8_t> items = HexBytes("0208 00046050584E0180");
  for (const auto& tlv : {Tlv(13, HexBytes("80000000")),  // signed indicator -> AddAbsent
                          Tlv(6, {}),                     // ZLI on a signed tag -> raw
                          Tlv(112, HexBytes("c800")),     // IMAPB +infinity -> raw
                          Tlv(113, HexBytes("d00000")),   // IMAPB NaN -> raw
                          Tlv(5, {}),                     // ZLI -> AddAbsent
                          Tlv(3, {}),                     // empty text -> AddAbsent
                          Tlv(65, HexBytes("11"))}) {
    items.insert(items.end(), tlv.begin(), tlv.end());
  }
  const KlvPacket packet = MakeSt0601Packet(items);
  auto set = DecodeSt0601(packet);
  ASSERT_TRUE(set.ok());
  ASSERT_TRUE(set->checksum_ok);
  for (uint32_t tag : {13u, 6u, 112u, 113u, 5u, 3u}) {
    EXPECT_TRUE(std::holds_alternative<Absent>(set->Find(tag)->value)) << tag;
  }
  ReencodeTally tally;
  const auto bytes = Reencode(*set, &tally);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  EXPECT_EQ(*bytes, packet.bytes);
  EXPECT_EQ(tally.absents, 3);
  EXPECT_EQ(tally.absents_kept_raw, 3);
}

}  // namespace
}  // namespace saker::klv
