"""rl_environments"""
