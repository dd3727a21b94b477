/*
 * tempfile.c - the temporary file beside an output, the registry of those
 * that exist and the fatal-signal policy; see tempfile.h.
 */
/* sync_file_range(), where Linux has it */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#ifdef __linux__
#include <sys/vfs.h>
#endif
#include <time.h>
#include <unistd.h>

#include "tempfile.h"

/*
 * The registry.  This is the program's one piece of mutable global state,
 * and it is global because a signal handler has no context argument: it
 * must find every writer's temporaries without one.  The handler reads only
 * lock-free atomic slot states (C11 7.14.1.1 allows them in a handler) and
 * the names of live slots; a name is written while its slot is reserved and
 * not live, under the mutex that also serialises the lookups of forget, so
 * the threads that create and retire temporaries never race on a name.
 */
#if ATOMIC_INT_LOCK_FREE != 2
#error "the temporary-file registry needs lock-free atomic int"
#endif
enum { SLOT_FREE, SLOT_LIVE };
static struct {
	atomic_int state;
	char name[PATH_MAX];
} live[TEMPFILE_MAX];
static pthread_mutex_t live_mu = PTHREAD_MUTEX_INITIALIZER;

/*
 * A temporary exists on disk from open(2) until live_add() has stored its
 * name: a signal in that window would find it in no slot and leave it
 * behind.  So a thread creates a temporary, and touches the registry at
 * all, with the fatal signals blocked (no handler then runs on a thread
 * holding live_mu or half-way through a creation), counted in creating;
 * the handler, on whichever thread it runs, first raises dying and then
 * waits for creating to reach zero.  A creator that finds dying raised
 * waits for the handler's _exit instead (both are sequentially consistent
 * atomics, so one of the two sees the other).
 */
static atomic_int creating, dying;

static void fatal_block(sigset_t *old)
{
	sigset_t set;

	sigemptyset(&set);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGTERM);
	sigaddset(&set, SIGHUP);
	pthread_sigmask(SIG_BLOCK, &set, old);
}

static void fatal_restore(const sigset_t *old)
{
	pthread_sigmask(SIG_SETMASK, old, NULL);
}
static char signal_msg[128] = "wfiscene: interrupted; partial output removed\n";
static size_t signal_len;

/* Register name; 0, or -1 when the registry is full or the name too long. */
static int live_add(const char *name)
{
	int r = -1;

	if (strlen(name) >= sizeof(live[0].name))
		return -1;
	pthread_mutex_lock(&live_mu);
	for (int i = 0; i < TEMPFILE_MAX; i++)
		if (atomic_load(&live[i].state) == SLOT_FREE) {
			strcpy(live[i].name, name);
			atomic_store(&live[i].state, SLOT_LIVE);
			r = 0;
			break;
		}
	pthread_mutex_unlock(&live_mu);
	return r;
}

static void live_forget(const char *name)
{
	sigset_t old;

	fatal_block(&old);
	pthread_mutex_lock(&live_mu);
	for (int i = 0; i < TEMPFILE_MAX; i++)
		if (atomic_load(&live[i].state) == SLOT_LIVE && !strcmp(live[i].name, name)) {
			atomic_store(&live[i].state, SLOT_FREE);
			break;
		}
	pthread_mutex_unlock(&live_mu);
	fatal_restore(&old);
}

void tempfile_remove_all(void)
{
	for (int i = 0; i < TEMPFILE_MAX; i++)
		if (atomic_load(&live[i].state) == SLOT_LIVE)
			unlink(live[i].name);
}

static void on_fatal_signal(int sig)
{
	/* one handler: a second signal on another thread waits for the
	 * first one's _exit */
	if (atomic_exchange(&dying, 1))
		for (;;)
			pause();
	/* the creators run with these signals blocked, never stop for this
	 * handler, and each takes an open(2) and a lock; about ten seconds
	 * (poll(2) is async-signal-safe) is for a file system that hangs */
	for (int i = 0; i < 10000 && atomic_load(&creating) > 0; i++)
		poll(NULL, 0, 1);
	tempfile_remove_all();
	if (write(STDERR_FILENO, signal_msg, signal_len) < 0)
		_exit(EXIT_SIGNAL);
	_exit(EXIT_SIGNAL);
}

void tempfile_signals(const char *prog)
{
	struct sigaction sa;

	snprintf(signal_msg, sizeof(signal_msg), "%.63s: interrupted; partial output removed\n",
		 prog);
	signal_len = strlen(signal_msg);
	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = on_fatal_signal;
	sigemptyset(&sa.sa_mask);
	/* one fatal signal at a time: a second waits for the first's _exit */
	sigaddset(&sa.sa_mask, SIGINT);
	sigaddset(&sa.sa_mask, SIGTERM);
	sigaddset(&sa.sa_mask, SIGHUP);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGHUP, &sa, NULL);
	sa.sa_handler = SIG_IGN;
	sigaction(SIGPIPE, &sa, NULL);
}

/* The last reference to a replaced file, dropped on its own thread. */
static void *release(void *fd)
{
	close((int)(intptr_t)fd);
	return NULL;
}

/* Close fd on a detached thread, made with the fatal signals blocked (their
 * handler then never runs on a thread held up in a slow close); at once if
 * no thread can be made. */
static void release_aside(int fd)
{
	pthread_attr_t at;
	pthread_t t;
	sigset_t mask;
	int ok;

	if (pthread_attr_init(&at)) {
		close(fd);
		return;
	}
	fatal_block(&mask);
	ok = !pthread_attr_setdetachstate(&at, PTHREAD_CREATE_DETACHED) &&
	     !pthread_attr_setstacksize(&at, 64 * 1024) &&
	     !pthread_create(&t, &at, release, (void *)(intptr_t)fd);
	fatal_restore(&mask);
	pthread_attr_destroy(&at);
	if (!ok)
		close(fd);
}

/*
 * The file path names, if the rename will free a regular file of
 * TEMPFILE_RELEASE_MIN bytes or more on a local file system, held across
 * that rename by a descriptor that opens nothing (O_PATH: no driver, FIFO
 * or lease sees it, and a symbolic link is the link itself): its last link
 * then goes without freeing its blocks, which happens when the descriptor
 * is closed.  On ext4 that freeing, inside rename(2), took 14 ms of a
 * 67 MB image (3 % of a 0.5 s run of 10^6 stars) and 0.35 s of a 1.2 GB
 * one.  Not on a network or FUSE file system, which keep a file open at
 * its rename under a hidden name until it is closed.  -1 when there is
 * none.
 */
static int replaced_open(const char *path)
{
#if defined(O_PATH) && defined(__linux__)
	struct stat st;
	struct statfs sf;
	int fd = open(path, O_PATH | O_NOFOLLOW | O_CLOEXEC);
	unsigned long ft;

	if (fd < 0)
		return -1;
	ft = fstatfs(fd, &sf) ? 0 : (unsigned long)sf.f_type;
	if (fstat(fd, &st) || !S_ISREG(st.st_mode) || st.st_nlink != 1 ||
	    (unsigned long long)st.st_blocks * 512 < TEMPFILE_RELEASE_MIN ||
	    (ft != 0xEF53UL /* ext2-4 */ && ft != 0x58465342UL /* xfs */ &&
	     ft != 0x9123683EUL /* btrfs */ && ft != 0x01021994UL /* tmpfs */)) {
		close(fd);
		return -1;
	}
	return fd;
#else
	(void)path;
	return -1;
#endif
}

int tempfile_commit(char *tmp, const char *path, struct err *e)
{
	int old = replaced_open(path);

	if (rename(tmp, path)) {
		err_sys(e, "%s: renaming '%s'", path, tmp);
		if (old >= 0)
			close(old);
		tempfile_discard(tmp);
		return -1;
	}
	live_forget(tmp);
	tmp[0] = 0;
	if (old >= 0)
		release_aside(old);
	return 0;
}

void tempfile_discard(char *tmp)
{
	int saved = errno;

	if (!tmp[0])
		return;
	unlink(tmp);
	live_forget(tmp);
	tmp[0] = 0;
	errno = saved;
}

/*
 * Create tmp and register it, as one step for the signal handler (see
 * creating above): with O_EXCL under the name tmp, or (unique) by
 * mkstemp(3) from the template tmp, which it completes.  The descriptor;
 * -1 with errno from open(2) or mkstemp(3); -2 when the registry is full
 * (nothing left on disk).
 */
static int create_registered(char *tmp, int unique)
{
	sigset_t old;
	int fd, saved;

	fatal_block(&old);
	atomic_fetch_add(&creating, 1);
	if (atomic_load(&dying)) {
		/* a handler is removing the temporaries and will _exit */
		atomic_fetch_sub(&creating, 1);
		for (;;)
			pause();
	}
	fd = unique ? mkstemp(tmp) : open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
	saved = errno;
	if (fd >= 0 && live_add(tmp) != 0) {
		close(fd);
		unlink(tmp);
		fd = -2;
	}
	atomic_fetch_sub(&creating, 1);
	fatal_restore(&old);
	errno = saved;
	return fd;
}

int tempfile_beside(const char *path, char *tmp, size_t cap, struct err *e)
{
	static const char alnum[] =
		"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
	const char *slash = strrchr(path, '/');
	const char *base = slash ? slash + 1 : path;
	struct timespec ts;
	uint64_t x;

	tmp[0] = 0;
	if (!*base)
		return err_set(e, EXIT_INPUT, "%s: not a file name", path);
	if (cap < TEMPFILE_SIZE(path)) {
		errno = ENAMETOOLONG;
		return err_sys(e, "%s", path);
	}
	/* names nobody else is likely to be trying: splitmix64 steps from
	 * the clock, the process and the caller's buffer */
	clock_gettime(CLOCK_REALTIME, &ts);
	x = (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30) ^
	    ((uint64_t)getpid() << 16) ^ (uint64_t)(uintptr_t)tmp;
	for (int attempt = 0; attempt < 100; attempt++) {
		uint64_t z = (x += 0x9E3779B97F4A7C15u);
		char suffix[7];
		int fd;

		z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
		z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
		z ^= z >> 31;
		for (int i = 0; i < 6; i++, z /= 62)
			suffix[i] = alnum[z % 62];
		suffix[6] = 0;
		snprintf(tmp, cap, "%.*s.%s.%s", (int)(base - path), path, base, suffix);
		fd = create_registered(tmp, 0);
		if (fd >= 0)
			return fd;
		if (fd == -2) {
			err_set(e, EXIT_SYSTEM, "%s: more than %d temporary files at once",
				path, TEMPFILE_MAX);
			tmp[0] = 0;
			return -1;
		}
		if (errno != EEXIST)
			break;
	}
	err_sys(e, "%s: cannot create temporary file '%s'", path, tmp);
	tmp[0] = 0;
	return -1;
}

int tempfile_open_output(const char *path, char *tmp, size_t cap, struct err *e)
{
	struct stat st;
	int fd;

	tmp[0] = 0;
	if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
		if (S_ISDIR(st.st_mode))
			return err_set(e, EXIT_INPUT, "%s: is a directory", path);
		if ((fd = open(path, O_WRONLY | O_CLOEXEC | O_NOCTTY)) < 0)
			return err_sys(e, "%s", path);
		return fd;
	}
	return tempfile_beside(path, tmp, cap, e);
}

int tempfile_scratch(const char *what, const char *stem, char *name, size_t cap,
		     struct err *e)
{
	const char *dir = getenv("TMPDIR");
	int fd;

	name[0] = 0;
	if (!dir || !*dir)
		dir = "/tmp";
	if (snprintf(name, cap, "%s/%s-XXXXXX", dir, stem) >= (int)cap) {
		name[0] = 0;
		return err_set(e, EXIT_SYSTEM, "%s: cannot create a temporary file in %s: "
			       "the name is too long", what, dir);
	}
	if ((fd = create_registered(name, 1)) == -2)
		err_set(e, EXIT_SYSTEM, "%s: more than %d temporary files at once", what,
			TEMPFILE_MAX);
	else if (fd < 0)
		err_sys(e, "%s: cannot create a temporary file in %s", what, dir);
	if (fd < 0)
		name[0] = 0;
	return fd;
}

int tempfile_unnamed(const char *what, struct err *e)
{
	char name[PATH_MAX];
	int fd = tempfile_scratch(what, "wfiscene", name, sizeof(name), e);

	if (fd >= 0)
		tempfile_discard(name);
	return fd;
}

long long tempfile_spool_stdin(struct err *e)
{
	char buf[1 << 16];
	long long total = 0;
	int fd = tempfile_unnamed("stdin", e);
	ssize_t r;

	if (fd < 0)
		return -1;
	while ((r = read(0, buf, sizeof(buf))) != 0) {
		if (r < 0 && errno == EINTR)
			continue;
		if (r < 0) {
			err_sys(e, "<stdin>: cannot read");
			goto fail;
		}
		for (char *p = buf; r > 0;) {
			ssize_t w = write(fd, p, (size_t)r);

			if (w < 0 && errno == EINTR)
				continue;
			if (w < 0) {
				err_sys(e, "<stdin>: cannot keep a copy for the passes over it "
					"(in $TMPDIR or /tmp)");
				goto fail;
			}
			p += w;
			r -= w;
			total += w;
		}
	}
	if (dup2(fd, 0) < 0 || lseek(0, 0, SEEK_SET) < 0) {
		err_sys(e, "<stdin>: temporary copy");
		goto fail;
	}
	close(fd);
	return total;
fail:
	close(fd);
	return -1;
}

long long tempfile_writeback(int fd, long long lo, long long hi)
{
	/* (no cached copy: any thread may ask, and libc answers from memory) */
	long page = sysconf(_SC_PAGESIZE);
	long long a, b;

	if (page <= 0)
		page = 4096;
	a = lo / page * page;
	b = hi / page * page;
	if (fd < 0 || lo < 0 || b <= a)
		return lo;
#ifdef SYNC_FILE_RANGE_WRITE
	(void)sync_file_range(fd, (off_t)a, (off_t)(b - a), SYNC_FILE_RANGE_WRITE);
	return b;
#else
	return lo;
#endif
}
