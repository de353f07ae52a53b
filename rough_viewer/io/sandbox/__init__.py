"""The reader sandbox: untrusted files decoded in a child process
(:mod:`.isolate`, the parent; :mod:`._child`, the child) under memory and time limits,
so that a hostile or damaged file cannot take the program down."""
