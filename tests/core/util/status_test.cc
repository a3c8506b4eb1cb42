#include "core/util/status.h"

#include "core/util/job_context.h"

#include <gtest/gtest.h>

namespace saker {
namespace {

StatusOr<int> ParsePositive(int value) {
  if (value <= 0)
    return InvalidArgumentError("value must be positive, got " + std::to_string(value));
  return value;
}

Status Chain(int value) {
  SAKER_RETURN_IF_ERROR(ParsePositive(value).status());
  return Status::Ok();
}

TEST(StatusTest, OkAndErrorCarryCodeAndMessage) {
  EXPECT_TRUE(Status::Ok().ok());
  const Status error = NotFoundError("clip.ts: no such file");
  EXPECT_FALSE(error.ok());
  EXPECT_EQ(error.code(), StatusCode::kNotFound);
  EXPECT_EQ(error.ToString(), "NotFound: clip.ts: no such file");
}

TEST(StatusTest, StatusOrHoldsValueOrError) {
  auto good = ParsePositive(3);
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 3);
  auto bad = ParsePositive(-1);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_THROW((void)bad.value(), CheckError);
}

TEST(StatusTest, ReturnIfErrorPropagates) {
  EXPECT_TRUE(Chain(1).ok());
  EXPECT_EQ(Chain(0).code(), StatusCode::kInvalidArgument);
}

TEST(CheckTest, FailedCheckThrowsWithFileLineAndMessage) {
  try {
    SAKER_CHECK(1 + 1 == 3) << "arithmetic is "
                            << "broken";
    FAIL() << "SAKER_CHECK did not throw";
  } catch (const CheckError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("status_test.cc"), std::string::npos) << what;
    EXPECT_NE(what.find("1 + 1 == 3"), std::string::npos) << what;
    EXPECT_NE(what.find("arithmetic is broken"), std::string::npos) << what;
  }
  EXPECT_NO_THROW(SAKER_CHECK(true) << "never evaluated");
}

TEST(JobContextTest, ReportsProgressAndCancel) {
  std::string stage;
  double fraction = -1;
  JobContext context([&](const std::string& s, double f) {
    stage = s;
    fraction = f;
  });
  context.ReportProgress("scan", 0.25);
  EXPECT_EQ(stage, "scan");
  EXPECT_DOUBLE_EQ(fraction, 0.25);
  EXPECT_FALSE(context.IsCancelled());
  context.RequestCancel();
  EXPECT_TRUE(context.IsCancelled());
}

}  // namespace
}  // namespace saker
