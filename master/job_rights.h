#pragma once
// Who may see and change a job: the one rule the client socket (broker_clients.cpp) and the HTTP
// endpoint (http_server.h, broker_http.cpp) both apply. A user is a client key's name; nullptr is
// a reader without a key (an HTTP request without a token).
#include <set>
#include <string>

namespace rayfarm::master {

struct JobRights {
  /// Keys that are neither the owner nor an admin cannot see a job (--private-jobs).
  bool private_jobs = false;
  /// Keys that may see and change every job (--admin-clients).
  std::set<std::string> admins;

  bool is_admin(const std::string* user) const { return user && admins.count(*user) != 0; }
  /// Cancel, pause, resume, set the priority of, remove, retry: the owner or an admin.
  bool may_manage(const std::string& owner, const std::string* user) const {
    return user && (owner == *user || is_admin(user));
  }
  /// Status, list, fetch.
  bool may_see(const std::string& owner, const std::string* user) const {
    return !private_jobs || may_manage(owner, user);
  }
};

}  // namespace rayfarm::master
