"""The edge aggregator: a site's gateway, a chief to its units and one member to its parent
(:mod:`.aggregator`), driven over two transports (:mod:`.runner`)."""
