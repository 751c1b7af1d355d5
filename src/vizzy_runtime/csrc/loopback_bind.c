/* LD_PRELOAD shim: a bind() to the wildcard address (INADDR_ANY or in6addr_any) binds loopback
 * instead.
 *
 * Why: Cyclone DDS binds its receive sockets to INADDR_ANY whatever its configuration
 * (ddsi_udp_create_conn, bind_to_any for RECV_UC/RECV_MC), so a node sending only on 127.0.0.1
 * would still be reachable from the LAN. vizzy_runtime.loopback starts the bundled runtime's
 * processes with this library preloaded unless VIZZY_DDS_LAN opts in to the network; the same
 * variable, read at every bind, turns the rewrite off in a process that opted in later.
 *
 * No Python symbols: the library is built as a setuptools extension only so that pip and colcon
 * compile and install it with the package; it is never imported.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

typedef int (*bind_fn)(int, const struct sockaddr *, socklen_t);

static int lan_opt_in(void) {
  const char *v = getenv("VIZZY_DDS_LAN");
  return v != NULL && (strcmp(v, "1") == 0 || strcmp(v, "true") == 0 || strcmp(v, "yes") == 0);
}

int bind(int fd, const struct sockaddr *addr, socklen_t len) {
  static bind_fn real_bind = NULL;
  if (real_bind == NULL) {
    real_bind = (bind_fn)dlsym(RTLD_NEXT, "bind");
    if (real_bind == NULL) {
      errno = ENOSYS;
      return -1;
    }
  }
  if (addr != NULL && !lan_opt_in()) {
    if (addr->sa_family == AF_INET && len >= (socklen_t)sizeof(struct sockaddr_in)) {
      struct sockaddr_in a;
      memcpy(&a, addr, sizeof a);
      if (a.sin_addr.s_addr == htonl(INADDR_ANY)) {
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        return real_bind(fd, (const struct sockaddr *)&a, sizeof a);
      }
    } else if (addr->sa_family == AF_INET6 && len >= (socklen_t)sizeof(struct sockaddr_in6)) {
      struct sockaddr_in6 a;
      memcpy(&a, addr, sizeof a);
      if (IN6_IS_ADDR_UNSPECIFIED(&a.sin6_addr)) {
        a.sin6_addr = in6addr_loopback;
        return real_bind(fd, (const struct sockaddr *)&a, sizeof a);
      }
    }
  }
  return real_bind(fd, addr, len);
}
