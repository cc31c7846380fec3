#pragma once

// The command-line tools (occgeo, occgeo replay, occgeo-sim, occgeo-load) declare their options with CLI11 through
// these helpers, so that they share one help layout and one error wording: "option '--flag' needs ..., got '...'",
// "unknown option '--flag'", "option '--flag' needs a value".

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/client/option_values.h"

namespace occgeo::client {

// A command-line mistake; the tools print it after their name, with a pointer to --help, and exit with 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The shared layout and parsing rules. Help is a plain --help/-h flag (the tools print their help themselves);
// unknown arguments are collected so that parse_command_line words them; a repeated option keeps its last value,
// as the tools always did.
inline void configure_cli(CLI::App& app, bool& help) {
  auto formatter = std::make_shared<CLI::Formatter>();
  formatter->column_width(32);
  formatter->label("REQUIRED", "");
  app.formatter(formatter);
  app.set_help_flag();
  app.add_flag("-h,--help", help, "print this help");
  app.allow_extras();
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
}

// The option CLI11 names at the start of an error, e.g. "--server" from "--server: 1 required TEXT missing".
inline std::string cli_option_name(const std::string& message) {
  return message.substr(0, message.find_first_of(": "));
}

// The option called `name` ("--flag") of app or one of its subcommands; nullptr when none is.
inline const CLI::Option* find_cli_option(const CLI::App& app, const std::string& name) {
  if (const CLI::Option* option = app.get_option_no_throw(name)) return option;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (const CLI::Option* option = find_cli_option(*sub, name)) return option;
  }
  return nullptr;
}

// Parses args (without the program name) into app; throws UsageError in the tools' wording. Arguments no option
// claims are left in app.remaining(true) (see refuse_extras).
inline void parse_cli_args(CLI::App& app, const std::vector<std::string>& args) {
  // A value never starts with "--": "--world --json" is a forgotten value, not a world called "--json".
  for (std::size_t i = 0; i < args.size(); ++i) {
    // A prefix command (occgeo replay) parses what follows it itself.
    const auto prefix = [&](const CLI::App* sub) { return sub->get_name() == args[i] && sub->get_prefix_command(); };
    const std::vector<CLI::App*> commands = app.get_subcommands([](const CLI::App*) { return true; });
    if (std::any_of(commands.begin(), commands.end(), prefix)) break;
    if (args[i].rfind("--", 0) != 0 || args[i].find('=') != std::string::npos) continue;
    const CLI::Option* option = find_cli_option(app, args[i]);
    if (option == nullptr || option->get_expected_min() == 0) continue;
    if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0) {
      throw UsageError("option '" + args[i] + "' needs a value");
    }
    ++i;
  }
  std::vector<std::string> reversed(args.rbegin(), args.rend());
  try {
    app.parse(reversed);
  } catch (const CLI::ArgumentMismatch& error) {
    const std::string message = error.what();
    if (message.find("flag override") != std::string::npos) {
      const std::string name = cli_option_name(message);
      throw UsageError("option '" + (name.rfind("-", 0) == 0 ? name : "--" + name) + "' takes no value");
    }
    throw UsageError("option '" + cli_option_name(message) + "' needs a value");
  } catch (const CLI::RequiredError& error) {
    throw UsageError(std::string("missing ") + error.what());
  } catch (const CLI::ParseError& error) {
    throw UsageError(error.what());
  }
}

// Refuses the arguments no option or positional of app (or a subcommand parsed) claimed.
inline void refuse_extras(const CLI::App& app) {
  for (const std::string& extra : app.remaining(true)) {
    if (extra.rfind("-", 0) == 0 && extra.size() > 1 && !finite_number(extra)) {
      throw UsageError("unknown option '" + extra.substr(0, extra.find('=')) + "'");
    }
    throw UsageError("unexpected argument '" + extra + "'");
  }
}

// parse_cli_args, then refuse_extras.
inline void parse_command_line(CLI::App& app, const std::vector<std::string>& args) {
  parse_cli_args(app, args);
  refuse_extras(app);
}

// --flag VALUE as a finite number (SI units), checked when parsed.
inline CLI::Option* add_number(CLI::App& app, const std::string& flag, double& out, const std::string& help) {
  return app
      .add_option_function<std::string>(
          flag,
          [flag, &out](const std::string& text) {
            const std::optional<double> value = finite_number(text);
            if (!value) throw UsageError("option '" + flag + "' needs a finite number, got '" + text + "'");
            out = *value;
          },
          help)
      ->type_name("X");
}

// --flag VALUE as a whole number in [min, max].
inline CLI::Option* add_whole(CLI::App& app, const std::string& flag, std::uint64_t& out, std::uint64_t min,
                              std::uint64_t max, const std::string& help) {
  return app
      .add_option_function<std::string>(
          flag,
          [flag, &out, min, max](const std::string& text) {
            std::uint64_t value = 0;
            const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
            if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
              throw UsageError("option '" + flag + "' needs a whole number, got '" + text + "'");
            }
            if (value < min || value > max) {
              throw UsageError("option '" + flag + "' needs a value in " + std::to_string(min) + ".." +
                               std::to_string(max) + ", got " + std::to_string(value));
            }
            out = value;
          },
          help)
      ->type_name("N");
}

// --flag VALUE kept as text; `check` (optional) turns it into the tool's value or throws UsageError.
inline CLI::Option* add_text(CLI::App& app, const std::string& flag, std::string& out, const std::string& help,
                             const std::string& type = "TEXT") {
  return app.add_option(flag, out, help)->type_name(type);
}

}  // namespace occgeo::client
