#include "epiloc/core/logging.h"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// The message with its control bytes shown as \xNN (Printable): warnings quote names and values
// from input files (a drive name holding ESC [2J or a line break), and one message stays one
// line that cannot drive the terminal.
class PrintablePayload : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg,
              const std::tm& /*time*/,
              spdlog::memory_buf_t& dest) override {
    const std::string text = Printable(std::string(msg.payload.data(), msg.payload.size()),
                                       msg.payload.size());
    dest.append(text.data(), text.data() + text.size());
  }
  std::unique_ptr<custom_flag_formatter> clone() const override {
    return std::make_unique<PrintablePayload>();
  }
};

}  // namespace

void InitLogging(Verbosity verbosity) {
  auto logger = spdlog::stderr_color_mt("epiloc");
  auto formatter = std::make_unique<spdlog::pattern_formatter>();
  formatter->add_flag<PrintablePayload>('*').set_pattern("%^[%l]%$ %*");
  logger->set_formatter(std::move(formatter));
  switch (verbosity) {
    case Verbosity::kQuiet:
      logger->set_level(spdlog::level::warn);
      break;
    case Verbosity::kNormal:
      logger->set_level(spdlog::level::info);
      break;
    case Verbosity::kVerbose:
      logger->set_level(spdlog::level::debug);
      break;
  }
  spdlog::set_default_logger(logger);
}

}  // namespace epiloc
