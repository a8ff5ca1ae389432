#include "cli/usage.h"

#include <algorithm>
#include <iostream>
#include <sstream>

namespace rayfarm::cli {
namespace {

/// Edit distance with adjacent transpositions counted as one edit ("sumbit" -> "submit": 1).
size_t distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

/// Every subcommand of `app` (named ones only).
std::vector<CLI::App*> subcommands_of(CLI::App& app) {
  return app.get_subcommands([](CLI::App* sub) { return !sub->get_name().empty(); });
}

/// "--spp", "-o", ... of `app`'s options, with the dashes.
std::vector<std::string> option_names(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::Option* opt : app.get_options()) {
    for (const auto& l : opt->get_lnames()) names.push_back("--" + l);
    for (const auto& s : opt->get_snames()) names.push_back("-" + s);
  }
  return names;
}

/// The "Usage: ..." line of `app`'s help, naming the program "rayfarm".
std::string usage_line(const CLI::App& app) {
  if (app.get_parent() == nullptr) return "Usage: rayfarm [OPTIONS] COMMAND ...";
  std::istringstream help(app.help());
  for (std::string line; std::getline(help, line);) {
    if (line.rfind("Usage: ", 0) == 0) return "Usage: rayfarm " + line.substr(7);
  }
  return "Usage: rayfarm " + app.get_name() + " [OPTIONS]";
}

}  // namespace

std::string near_miss(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  size_t best_distance = 3;  // at most two edits...
  for (const std::string& c : candidates) {
    if (c == word) return "";
    const size_t d = distance(word, c);
    // ...and fewer than half the word's letters: "--x" is not a near miss of "--spp".
    if (d < best_distance && 2 * d < std::max(word.size(), c.size())) {
      best = c;
      best_distance = d;
    }
  }
  if (best.empty()) {  // a name cut short: "--thr" for "--threads"
    const size_t letters = word.size() - std::min(word.find_first_not_of('-'), word.size());
    for (const std::string& c : candidates) {
      if (letters >= 2 && c.size() > word.size() && c.compare(0, word.size(), word) == 0) {
        if (!best.empty()) return "";  // ambiguous
        best = c;
      }
    }
  }
  return best;
}

int usage_error(CLI::App& app, int argc, char** argv, const CLI::ParseError& e) {
  std::vector<std::string> args(argv + 1, argv + argc);
  // The command given, if any; a near miss of one otherwise.
  CLI::App* command = nullptr;
  std::vector<std::string> command_names;
  for (CLI::App* sub : subcommands_of(app)) command_names.push_back(sub->get_name());
  std::string suggestion;
  size_t first = args.size();
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i].empty() || args[i][0] == '-') continue;
    if (i > 0 && (args[i - 1] == "--log-level" || args[i - 1] == "--log-format")) continue;
    first = i;
    break;
  }
  if (first < args.size()) {
    for (CLI::App* sub : subcommands_of(app)) {
      if (sub->get_name() == args[first]) command = sub;
    }
    if (!command) suggestion = near_miss(args[first], command_names);
  }
  // Options the command does not have: a near miss of one it has.
  if (command && suggestion.empty()) {
    std::vector<std::string> names = option_names(*command);
    const std::vector<std::string> top = option_names(app);
    names.insert(names.end(), top.begin(), top.end());
    for (size_t i = first + 1; i < args.size() && suggestion.empty(); ++i) {
      const std::string word = args[i].substr(0, args[i].find('='));
      if (word.size() < 2 || word[0] != '-' || word == "--") continue;
      if (std::find(names.begin(), names.end(), word) != names.end()) continue;
      suggestion = near_miss(word, names);
    }
  }
  const std::string what = !command && first < args.size()
                               ? "unknown command '" + args[first] + "'"
                               : std::string(e.what());
  std::cerr << "rayfarm" << (command ? " " + command->get_name() : "") << ": error: " << what
            << "\n";
  if (!suggestion.empty()) std::cerr << "did you mean '" << suggestion << "'?\n";
  std::cerr << usage_line(command ? *command : app) << "\n"
            << "Run 'rayfarm" << (command ? " " + command->get_name() : "")
            << " --help' for more.\n";
  return kExitUsage;
}

void add_completion_command(CLI::App& app, int& exit_code) {
  CLI::App* cmd = app.add_subcommand(
      "completion", "Print a shell completion script (bash): see docs/cli.md to install it");
  auto shell = std::make_shared<std::string>();
  cmd->add_option("shell", *shell, "The shell: bash")->required()->check(CLI::IsMember({"bash"}));
  cmd->callback([&app, &exit_code] {
    std::ostringstream cases;
    std::string commands;
    for (CLI::App* sub : subcommands_of(app)) {
      commands += (commands.empty() ? "" : " ") + sub->get_name();
      std::string options;
      for (const std::string& name : option_names(*sub)) options += " " + name;
      cases << "    " << sub->get_name() << ") opts=\"" << options.substr(1) << "\" ;;\n";
    }
    std::string top;
    for (const std::string& name : option_names(app)) top += " " + name;
    std::cout << "# bash completion for rayfarm; generated by `rayfarm completion bash`.\n"
                 "_rayfarm() {\n"
                 "  local cur=\"${COMP_WORDS[COMP_CWORD]}\" cmd=\"\" i opts\n"
                 "  for ((i = 1; i < COMP_CWORD; i++)); do\n"
                 "    case \"${COMP_WORDS[i]}\" in -*) ;; *) cmd=\"${COMP_WORDS[i]}\"; break ;; esac\n"
                 "  done\n"
                 "  if [[ -z \"$cmd\" ]]; then\n"
                 "    COMPREPLY=($(compgen -W \""
              << commands << top
              << "\" -- \"$cur\"))\n"
                 "    return\n"
                 "  fi\n"
                 "  case \"$cmd\" in\n"
              << cases.str()
              << "    *) opts=\"\" ;;\n"
                 "  esac\n"
                 "  if [[ \"$cur\" == -* ]]; then\n"
                 "    COMPREPLY=($(compgen -W \"$opts\" -- \"$cur\"))\n"
                 "  else\n"
                 "    COMPREPLY=($(compgen -f -- \"$cur\"))\n"
                 "  fi\n"
                 "}\n"
                 "complete -o filenames -o bashdefault -F _rayfarm rayfarm\n";
    exit_code = 0;
  });
}

}  // namespace rayfarm::cli
