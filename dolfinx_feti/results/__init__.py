"""What a solve returns: the Solution, its report, the mortar checks, output and plots."""
