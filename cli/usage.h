#pragma once
// How `rayfarm` answers a command line it cannot parse, and the shell completion it generates
// from its own commands and options (so the two never disagree).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace rayfarm::cli {

/// Exit code of a usage error: an unknown command or option, a missing or bad argument.
inline constexpr int kExitUsage = 2;

/// The closest of `candidates` to `word` when it is a near miss (a typo, a transposition, a cut
/// short name), else "".
std::string near_miss(const std::string& word, const std::vector<std::string>& candidates);

/// Prints the parse error `e`, a suggestion for a near miss in argv ("did you mean 'submit'?",
/// "did you mean '--spp'?") and the usage line of the command; returns kExitUsage.
int usage_error(CLI::App& app, int argc, char** argv, const CLI::ParseError& e);

/// `rayfarm completion bash`: prints a bash completion script for every command and option.
void add_completion_command(CLI::App& app, int& exit_code);

}  // namespace rayfarm::cli
