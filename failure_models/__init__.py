# failure models shipped with pyroute_rel (data, not code)
