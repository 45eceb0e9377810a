"""Communication patterns over the ranks: exchanges with directories, distributed graphs."""
