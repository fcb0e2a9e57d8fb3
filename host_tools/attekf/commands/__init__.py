"""Sub-commands of ``attekf``: one module each (NAME, HELP, add_arguments, run)."""
