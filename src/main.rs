//! The `maaf` command-line tool (every command and option: docs/cli.md): the
//! library's command line with the built-in loss terms ([`maaf::cli::Maaf`]).

/// The binary allocates through mimalloc, which keeps freed pages mapped
/// ([`maaf::alloc`] says why); the library leaves the allocator to the program.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    maaf::alloc::keep_freed_pages();
    maaf::cli::Maaf::new().run()
}
