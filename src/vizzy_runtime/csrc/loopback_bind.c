/* A bind() to the wildcard address (INADDR_ANY or in6addr_any) binds loopback instead.
 *
 * Why: Cyclone DDS binds its receive sockets to INADDR_ANY whatever its configuration
 * (ddsi_udp_create_conn, bind_to_any for RECV_UC/RECV_MC), so a node sending only on 127.0.0.1
 * would still be reachable from the LAN. Two ways in, both from vizzy_runtime.loopback:
 *
 * - LD_PRELOAD: the exported bind() below interposes every bind of the process (the launcher
 *   starts nodes so, and entry points re-execute themselves so);
 * - a process that only imports the runtime (pytest, a user's script) cannot be preloaded any
 *   more, so vizzy_loopback_patch() rewrites the bind entry of the Cyclone library's own global
 *   offset table (its PLT slot) to the same rewrite: only that library's binds change.
 *
 * The VIZZY_DDS_LAN opt-in, read at every bind, turns the rewrite off. No Python symbols: the
 * library is built as a setuptools extension only so that pip and colcon compile and install it
 * with the package; Python reaches it through ctypes.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <link.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

typedef int (*bind_fn)(int, const struct sockaddr *, socklen_t);

static int lan_opt_in(void) {
  const char *v = getenv("VIZZY_DDS_LAN");
  return v != NULL && (strcmp(v, "1") == 0 || strcmp(v, "true") == 0 || strcmp(v, "yes") == 0);
}

/* libc's own bind: found in libc itself, so that neither the preloaded bind() below nor a patched
 * slot can call back into this file. */
static bind_fn libc_bind(void) {
  static bind_fn real = NULL;
  if (real == NULL) {
    void *libc = dlopen("libc.so.6", RTLD_LAZY | RTLD_NOLOAD);
    if (libc != NULL) real = (bind_fn)dlsym(libc, "bind");
    if (real == NULL) real = (bind_fn)dlsym(RTLD_NEXT, "bind");
  }
  return real;
}

static int loopback_bind(int fd, const struct sockaddr *addr, socklen_t len) {
  bind_fn real_bind = libc_bind();
  if (real_bind == NULL) {
    errno = ENOSYS;
    return -1;
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

int bind(int fd, const struct sockaddr *addr, socklen_t len) { return loopback_bind(fd, addr, len); }

/* --- the PLT patch ------------------------------------------------------------------------- */

#if defined(__x86_64__)
#define SLOT_RELOC R_X86_64_JUMP_SLOT
#define GOT_RELOC R_X86_64_GLOB_DAT
#elif defined(__aarch64__)
#define SLOT_RELOC R_AARCH64_JUMP_SLOT
#define GOT_RELOC R_AARCH64_GLOB_DAT
#endif

struct patch_request {
  const char *name_part; /* a loaded object whose path contains this */
  int objects;           /* such objects seen */
  int patched;           /* bind slots rewritten */
  int failed;            /* slots that could not be made writable */
};

#ifdef SLOT_RELOC
/* glibc relocates the d_ptr entries of a loaded object's dynamic section in place; other loaders
 * may not, hence the base added to an address below it. */
static uintptr_t dyn_addr(uintptr_t base, uintptr_t ptr) { return ptr < base ? ptr + base : ptr; }

static void patch_relocs(const ElfW(Rela) *rel, size_t size, const ElfW(Sym) *symtab,
                         const char *strtab, const struct dl_phdr_info *info,
                         struct patch_request *req) {
  uintptr_t page = (uintptr_t)sysconf(_SC_PAGESIZE);
  for (size_t i = 0; rel != NULL && i < size / sizeof *rel; i++) {
    unsigned type = (unsigned)ELF64_R_TYPE(rel[i].r_info);
    if (type != SLOT_RELOC && type != GOT_RELOC) continue;
    const ElfW(Sym) *sym = &symtab[ELF64_R_SYM(rel[i].r_info)];
    if (strcmp(strtab + sym->st_name, "bind") != 0) continue;
    void **slot = (void **)(info->dlpi_addr + rel[i].r_offset);
    if (*slot == (void *)loopback_bind) continue;
    /* Under full RELRO the slot is read-only once relocated: open it for the write, then close
     * it again; a writable slot (partial RELRO, .got.plt) is written as it is. */
    int relro = 0;
    for (int p = 0; p < info->dlpi_phnum; p++) {
      const ElfW(Phdr) *ph = &info->dlpi_phdr[p];
      uintptr_t start = info->dlpi_addr + ph->p_vaddr;
      if (ph->p_type == PT_GNU_RELRO && (uintptr_t)slot >= start &&
          (uintptr_t)slot < start + ph->p_memsz)
        relro = 1;
    }
    void *slot_page = (void *)((uintptr_t)slot & ~(page - 1));
    if (relro && mprotect(slot_page, page, PROT_READ | PROT_WRITE) != 0) {
      req->failed++;
      continue;
    }
    *slot = (void *)loopback_bind;
    if (relro) mprotect(slot_page, page, PROT_READ);
    req->patched++;
  }
}

static int patch_object(struct dl_phdr_info *info, size_t size, void *data) {
  (void)size;
  struct patch_request *req = data;
  if (info->dlpi_name == NULL || strstr(info->dlpi_name, req->name_part) == NULL) return 0;
  req->objects++;
  const ElfW(Dyn) *dyn = NULL;
  for (int p = 0; p < info->dlpi_phnum; p++)
    if (info->dlpi_phdr[p].p_type == PT_DYNAMIC)
      dyn = (const ElfW(Dyn) *)(info->dlpi_addr + info->dlpi_phdr[p].p_vaddr);
  if (dyn == NULL) return 0;
  uintptr_t base = info->dlpi_addr;
  const ElfW(Sym) *symtab = NULL;
  const char *strtab = NULL;
  const ElfW(Rela) *jmprel = NULL, *rela = NULL;
  size_t jmprel_size = 0, rela_size = 0;
  for (; dyn->d_tag != DT_NULL; dyn++) {
    switch (dyn->d_tag) {
      case DT_SYMTAB: symtab = (const ElfW(Sym) *)dyn_addr(base, dyn->d_un.d_ptr); break;
      case DT_STRTAB: strtab = (const char *)dyn_addr(base, dyn->d_un.d_ptr); break;
      case DT_JMPREL: jmprel = (const ElfW(Rela) *)dyn_addr(base, dyn->d_un.d_ptr); break;
      case DT_PLTRELSZ: jmprel_size = dyn->d_un.d_val; break;
      case DT_RELA: rela = (const ElfW(Rela) *)dyn_addr(base, dyn->d_un.d_ptr); break;
      case DT_RELASZ: rela_size = dyn->d_un.d_val; break;
      default: break;
    }
  }
  if (symtab == NULL || strtab == NULL) return 0;
  patch_relocs(jmprel, jmprel_size, symtab, strtab, info, req);
  patch_relocs(rela, rela_size, symtab, strtab, info, req);
  return 0;
}
#endif

/* Rewrite the bind slots of every loaded object whose path contains name_part. Returns the slots
 * now bound to loopback_bind (already patched ones are not counted again), -1 when no such
 * object is loaded, -2 when a slot could not be written, -3 on an unsupported architecture. */
int vizzy_loopback_patch(const char *name_part) {
#ifdef SLOT_RELOC
  struct patch_request req = {name_part, 0, 0, 0};
  dl_iterate_phdr(patch_object, &req);
  if (req.objects == 0) return -1;
  if (req.failed) return -2;
  return req.patched;
#else
  (void)name_part;
  return -3;
#endif
}
