"""photons"""
