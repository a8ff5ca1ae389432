// `rayfarm keygen`: writes a CURVE key pair for a master, a worker or a client.
#include <iostream>

#include <fmt/format.h>

#include "cli/commands.h"
#include "common/net/keys.h"

namespace rayfarm::cli {

void add_keygen_command(CLI::App& app, int& exit_code) {
  struct Args {
    std::string dir = ".";
    std::string name = "rayfarm";
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "keygen",
      "Write a CURVE key pair: DIR/NAME.key (public: give it to the master's allow-list, or to "
      "workers and clients for the master's key) and DIR/NAME.key_secret (mode 0600: keep it "
      "on this machine)");
  cmd->add_option("-o,--dir", args->dir, "folder to write the two files in (created if needed)")
      ->capture_default_str();
  cmd->add_option("--name", args->name,
                  "name of the key: the files' names, and the peer's name in the master's log")
      ->capture_default_str();
  cmd->callback([args, &exit_code] {
    try {
      const net::KeyFiles files =
          net::write_key_pair(args->dir, args->name, net::generate_key_pair());
      const std::string public_key = net::read_public_key(files.public_file);
      std::cout << fmt::format("wrote {} (public key {})\n  and {} (secret, mode 0600)\n",
                               files.public_file.string(), public_key, files.secret_file.string());
      exit_code = 0;
    } catch (const std::exception& e) {
      std::cerr << "rayfarm keygen: error: " << e.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace rayfarm::cli
