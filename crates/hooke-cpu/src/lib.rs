pub fn placeholder_until_solver() {}
