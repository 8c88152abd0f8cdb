"""The NCK: its variables and the parts behind them (axes, sensors, compensation, channels, programs,
PI services, alarms, tools, frames), one module each behind ``model.NckModel``."""
