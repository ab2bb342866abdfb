"""dancekit.models"""
