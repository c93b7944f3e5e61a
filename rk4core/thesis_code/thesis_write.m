function thesis_write(file, t, Y, nfev)
% THESIS_WRITE  Write a trajectory in the harness' protocol (rk4core/command.py):
% FILE gets the header "t,y1,...,yN" and one row per time t(i): t(i), Y(i,:),
% all printed with 17 significant digits (round trip exact). With NFEV,
% stats.json beside FILE gets {"nfev": NFEV}.
  t = t(:);
  if rows(Y) ~= numel(t)
    error('thesis_write: %d times but %d states', numel(t), rows(Y));
  end
  n = columns(Y);
  fid = fopen(file, 'w');
  if fid < 0
    error('thesis_write: cannot write %s', file);
  end
  fprintf(fid, '%s\n', ['t', sprintf(',y%d', 1:n)]);
  fprintf(fid, [repmat('%.17g,', 1, n), '%.17g\n'], [t, Y]');
  if fclose(fid) ~= 0
    error('thesis_write: cannot close %s', file);
  end
  if nargin > 3 && ~isempty(nfev)
    fid = fopen(fullfile(fileparts(file), 'stats.json'), 'w');
    if fid < 0
      error('thesis_write: cannot write stats.json beside %s', file);
    end
    fprintf(fid, '{"nfev": %d}\n', round(nfev));
    fclose(fid);
  end
end
