// rayfarm: the command-line tool (render locally, compare images, talk to a farm).
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "cli/commands.h"
#include "cli/usage.h"
#include "common/protocol/version.h"
#include "common/util/log_options.h"

int main(int argc, char** argv) {
  CLI::App app{"rayfarm: a distributed path tracer"};
  app.require_subcommand(1);
  app.set_version_flag("--version", rayfarm::protocol::kBuildVersion, "Print the version and exit");
  rayfarm::LoggingOptions logging;
  rayfarm::add_logging_options(app, logging);
  app.parse_complete_callback([&logging] { logging.apply(); });

  int exit_code = 0;
  rayfarm::cli::add_render_command(app, exit_code);
  rayfarm::cli::add_compare_command(app, exit_code);
  rayfarm::cli::add_farm_commands(app, exit_code);
  rayfarm::cli::add_keygen_command(app, exit_code);
  rayfarm::cli::add_report_command(app, exit_code);
  rayfarm::cli::add_completion_command(app, exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // A usage error: what is wrong, a near miss when there is one, and the usage line.
    return rayfarm::cli::usage_error(app, argc, argv, e);
  } catch (const std::exception& e) {
    std::cerr << "rayfarm: error: " << e.what() << "\n";
    return 1;
  }
  return exit_code;
}
