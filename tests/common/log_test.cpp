// --log-format json: every record is one JSON object whose "msg" is the message, whatever it holds.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "common/util/log.h"

namespace rayfarm {
namespace {

TEST(LogTest, JsonRecordsStayValidWithQuotesBackslashesAndControlCharacters) {
  configure_logging("info", LogFormat::kJson);
  const std::string message = "scene \"a.json\": C:\\path\tline\nnext \x01 end";
  ::testing::internal::CaptureStderr();
  auto logger = get_logger("logtest");
  logger->info("{}", message);
  logger->flush();
  const std::string out = ::testing::internal::GetCapturedStderr();
  configure_logging("info", LogFormat::kText);
  std::istringstream lines(out);
  std::string line;
  ASSERT_TRUE(std::getline(lines, line)) << "no record written";
  const nlohmann::json record = nlohmann::json::parse(line);  // throws on invalid JSON
  EXPECT_EQ(record.at("msg").get<std::string>(), message);
  EXPECT_EQ(record.at("logger").get<std::string>(), "logtest");
  EXPECT_EQ(record.at("level").get<std::string>(), "info");
  EXPECT_FALSE(std::getline(lines, line)) << "one record must be one line";
}

TEST(LogTest, UnknownLevelIsRejected) {
  EXPECT_THROW(configure_logging("loud"), std::invalid_argument);
}

}  // namespace
}  // namespace rayfarm
